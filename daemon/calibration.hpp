#pragma once
// The operator's calibration session inside mfcd (mfcd-ctl calibrate ..., docs/operations.md).
//
// Board detection, calibrateCamera, the hand-eye solvers and Ceres take from tens of
// milliseconds to seconds, so none of it runs on the main thread (which answers the PLC and
// feeds the systemd watchdog) or on the frame path: every session operation is a job run in
// order by this class's own worker thread, and the main thread picks up each job's answer
// through completion_fd() in its poll loop. The CalibrationSession itself is touched only by
// the worker; the main thread keeps the copy of its state that the last job reported.
//
// Images come from the cell's acquisition path (the ambient image of a calibration capture);
// the main thread hands a copy of each to the worker.
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "base/unique_fd.hpp"
#include "daemon/config.hpp"
#include "vision/calib/session.hpp"

namespace mfcd::daemon {

class CalibrationService {
 public:
  enum class Kind { Intrinsics, HandEye };

  // Control clients are named by the daemon's id for them (a closed client's fd may be reused).
  using ClientId = std::uint64_t;

  // One finished job: the answer for `client`, and what the main thread must do.
  struct Done {
    ClientId client = 0;
    nlohmann::json reply;
    bool reload = false;  // the camera file changed: reload the cell so it uses it
  };

  CalibrationService();
  ~CalibrationService();
  CalibrationService(const CalibrationService&) = delete;
  CalibrationService& operator=(const CalibrationService&) = delete;

  // --- main thread ---
  int completion_fd() const { return done_fd_.get(); }
  std::vector<Done> take_done();  // drains completion_fd()
  bool busy() const { return pending_ > 0; }
  const std::string& working() const { return working_; }  // the job running, when busy
  bool active() const { return state_.value("active", false); }
  bool hand_eye() const { return state_.value("kind", "") == "hand-eye"; }
  bool eye_in_hand() const { return state_.value("mode", "") == "eye-in-hand"; }
  bool computed() const { return state_.value("computed", false); }
  // {"active", "kind", "mode", "file", "views", "computed", "figures"}
  const nlohmann::json& state() const { return state_; }

  // Each posts a job answered through completion_fd(); the caller checks busy() first.
  void start(ClientId client, Kind kind, vision::calib::HandEyeMode mode, const fs::path& camera_file,
             const CalibrationSettings& settings);
  void add_view(ClientId client, cv::Mat1b image, std::optional<vision::calib::RobotPose> flange, nlohmann::json about);
  void compute(ClientId client);
  void check(ClientId client, cv::Mat1b image, vision::calib::RobotPose flange, nlohmann::json about);
  // Writes the camera file; then checks every recipe's template file against the new camera
  // (vision::check_template_camera) and names in the reply ("invalidated": recipe, part, file,
  // why) and the log the recipes to re-teach. The cell reloads on the new file afterwards.
  void apply(ClientId client, std::vector<RecipeConfig> recipes);
  void abort(ClientId client);
  void rollback(ClientId client, const fs::path& camera_file);

 private:
  void post(ClientId client, std::string what, std::function<Done()> job);
  void worker_main();
  nlohmann::json session_state() const;  // worker

  // Worker-only.
  std::unique_ptr<vision::calib::CalibrationSession> session_;
  fs::path file_;
  std::string mode_;
  std::string figures_;
  int captures_ = 0;

  // Main-thread-only.
  int pending_ = 0;  // jobs posted and not yet answered
  std::string working_;
  nlohmann::json state_ = {{"active", false}};

  std::mutex mutex_;  // jobs_, done_, stop_
  std::condition_variable wake_;
  std::deque<std::function<void()>> jobs_;
  std::vector<std::pair<Done, nlohmann::json>> done_;  // reply + session state after the job
  bool stop_ = false;
  UniqueFd done_fd_;
  std::thread worker_;
};

// The recipes whose template file `camera_file` invalidates (vision::check_template_camera, or the
// file cannot be read), each as {"recipe", "part", "templates", "why"}; recipes without templates
// are skipped. Loads every .tdb: run it off the main thread. Throws when camera_file is unreadable.
nlohmann::json invalidated_recipes(const fs::path& camera_file, const std::vector<RecipeConfig>& recipes);

// "x,y,z,rx,ry,rz" as the JSON array mfcd-ctl sends, checked: six finite numbers. Throws
// std::invalid_argument naming `what`.
vision::calib::RobotPose pose_from_json(const nlohmann::json& j, const std::string& what);

}  // namespace mfcd::daemon
