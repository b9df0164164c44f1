#pragma once
// Private to mfcd: the Daemon class, whose member functions live in four files by concern:
//   daemon.cpp              lifecycle (start, run loop, signals, reload, watchdog and HEARTBEAT lease)
//   daemon_cycles.cpp       cycles: start, results, the robot link's report, every job answered
//   daemon_commands.cpp     the control socket's command table and status
//   daemon_calibration.cpp  mfcd-ctl calibrate
// The pieces it composes are classes of their own: Cell (frame path), RobotLink (Modbus + CAN),
// ControlServer (control socket), EventLoop (the main thread's poll loop), CalibrationService.
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "base/unique_fd.hpp"
#include "daemon/calibration.hpp"
#include "daemon/cell.hpp"
#include "daemon/config.hpp"
#include "daemon/control_server.hpp"
#include "daemon/cycle_stats.hpp"
#include "daemon/daemon.hpp"
#include "daemon/event_loop.hpp"
#include "daemon/robot_link.hpp"
#include "daemon/web_server.hpp"
#include "daemon/web_view.hpp"

namespace mfcd::daemon {

using ClientId = ControlServer::ClientId;

// A control client waiting for the cycle it started.
// Robot-link commands that start a job (each ends with a result or an error code).
inline bool starts_job(motion::PlcCommand::Kind k) {
  using Kind = motion::PlcCommand::Kind;
  return k == Kind::Trigger || k == Kind::SaveScene || k == Kind::Look || k == Kind::CheckGrip;
}

struct Waiter {
  ClientId client;
  std::uint64_t cycle;
  enum class What { Trigger, Snapshot } what;
};

class Daemon {
 public:
  Daemon(DaemonOptions options, VisionStageFactory vision, FrameSourceFactory source)
      : options_(std::move(options)), vision_(std::move(vision)), source_(std::move(source)) {}
  int run();

 private:
  DaemonConfig load() const;
  void start_cell(const DaemonConfig& config);
  // Stops the cell (LEDs off, devices released), after the web view has let go of its frames.
  void drop_cell();
  // Hands the running cell's frames, parts and camera to the web view (when it runs).
  void show_cell_on_web(const DaemonConfig& config);
  void watch_cell();  // (re-)registers the current cell's result fd with the loop
  void lock_memory();
  bool start_services();
  void main_loop();
  void shutdown();
  void on_signal();
  void on_cell_results();
  void on_plc_commands();

  // daemon_commands.cpp
  void register_commands();
  nlohmann::json status_json() const;
  void start_control_cycle(ClientId client, const RequestArgs& args, bool snapshot);
  void select_part(ClientId client, const RequestArgs& args);
  // daemon_calibration.cpp
  bool calibrating() const { return calib_ && (calib_->active() || calib_->busy() || capture_); }
  void handle_calibrate(ClientId client, const nlohmann::json& req);
  void on_calibration_image(const CycleResult& r);
  void on_calibration_done();

  // daemon_cycles.cpp
  // A first look whose result asked for a second (the robot link's LOOK continues it).
  struct FirstLook {
    std::uint16_t job = 0;
    std::uint64_t cycle = 0;
    Eigen::Isometry3d base_T_flange = Eigen::Isometry3d::Identity();
  };
  // `first`: the cycle is a second look fused with that first look.
  std::optional<std::uint64_t> start_cycle(CycleOrigin origin, std::uint16_t job, std::uint16_t recipe,
                                           std::uint16_t mode, bool snapshot, const FirstLook* first = nullptr);
  void on_plc_command(const motion::PlcCommand& cmd);
  // NEXT (already published by the Modbus server): the report follows with that pick.
  void on_next_pick(const motion::PlcCommand& cmd);
  // PICK_RESULT: counted, logged, and a failed pick's frame set saved (snapshots.on_failed_pick).
  void on_pick_result(const motion::PlcCommand& cmd);
  // A PLC or continuous job's result into the robot link's report, with its ranked picks.
  void report_job(const CycleResult& r);
  // Starts a TRIGGER's (or SAVE_SCENE's) cycle now, or answers the job with ERROR_CODE 7 when the cell cannot take it.
  void start_plc_job(const motion::PlcCommand& cmd);
  // Ends a PLC job that will not run: JOB_ID_ECHO = job, PICK_VALID 0, ERROR_CODE = error.
  void answer_job(std::uint16_t job, std::uint16_t recipe, CycleError error, const char* why);
  // daemon_grip.cpp: CHECK_GRIP of the pick published last, and its result.
  void start_grip_check(const motion::PlcCommand& cmd);
  void on_grip_result(const CycleResult& r);
  void clear_grip();  // no grip result in the report
  // No second look wanted in the report, and none kept.
  void clear_look();
  // Hands a request to the cell and extends the time its threads may be busy with it.
  bool submit(const CycleRequest& r);
  void on_result(const CycleResult& r);
  void after_cycle();
  void publish();
  void update_ready();

  // daemon.cpp
  bool reload(std::string& message);
  void notify_status();
  void on_timer();
  // True while every frame-path thread has woken within `grace`, or is allowed to be busy with
  // a request (until that request's deadline + grace).
  bool frame_path_moving(Clock::time_point now, std::chrono::milliseconds grace) const;
  int run_benchmark();

  DaemonOptions options_;
  VisionStageFactory vision_;
  FrameSourceFactory source_;
  DaemonConfig config_;
  EventLoop loop_;
  ControlServer control_{loop_};
  RobotLink link_;
  std::unique_ptr<Cell> cell_;
  std::unique_ptr<WebView> web_view_;  // web.enabled: what the web server shows
  std::unique_ptr<WebServer> web_;
  int watched_cell_fd_ = -1;
  motion::RobotReport report_;
  CycleStats stats_;
  nlohmann::json last_result_;

  std::optional<CycleRequest> in_flight_;
  std::optional<motion::PlcCommand> pending_plc_;
  std::vector<Waiter> waiters_;
  std::vector<std::pair<ClientId, nlohmann::json>> reload_waiters_;  // client, and what to add to the reload's answer
  std::uint64_t next_cycle_ = 1;
  std::uint16_t next_continuous_job_ = 1;
  std::uint64_t last_job_cycle_ = 0;     // cycle of the job in the robot link's report (0: none)
  std::optional<FirstLook> first_look_;  // the report's job asks for a second look
  // The picks in the robot link's report (CHECK_GRIP checks one of them): job 0 when none.
  struct PublishedPicks {
    std::uint16_t job = 0, recipe = 0, count = 0;
    std::array<int, motion::kMaxRankedPicks> obj_id{};  // per rank
  };
  PublishedPicks last_pick_;
  int selected_recipe_ = 0;
  bool reload_pending_ = false, stopping_ = false, cell_ok_ = false;
  Clock::time_point stop_requested_{};

  UniqueFd signal_fd_, timer_fd_;

  // mfcd-ctl calibrate: the session runs on the service's worker; a capture in flight waits here
  // for its frame set.
  struct PendingCapture {
    ClientId client = 0;
    std::uint64_t cycle = 0;
    bool check = false;
    std::optional<vision::calib::RobotPose> flange;
    nlohmann::json about;
  };
  std::unique_ptr<CalibrationService> calib_;
  std::optional<PendingCapture> capture_;
  std::optional<std::uint16_t> last_plc_pose_seq_;
  std::uint64_t watchdog_usec_ = 0;
  std::uint64_t last_acq_beat_ = 0, last_vision_beat_ = 0;
  Clock::time_point acq_moved_ = Clock::now(), vision_moved_ = Clock::now();
  std::string last_status_;
  bool stuck_logged_ = false;
  bool link_down_logged_ = false;
  bool frames_ok_ = true;           // the last cycle captured and ran its vision stage (VISION_OK)
  Clock::time_point busy_until_{};  // the latest deadline of a request handed to the cell
};

}  // namespace mfcd::daemon
