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
#include "motion/unique_fd.hpp"

namespace mfcd::daemon {

using ClientId = ControlServer::ClientId;

// A control client waiting for the cycle it started.
// Robot-link commands that start a job (each ends with a result or an error code).
inline bool startsJob(motion::PlcCommand::Kind k) {
  using Kind = motion::PlcCommand::Kind;
  return k == Kind::Trigger || k == Kind::SaveScene || k == Kind::Look;
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
  void startCell(const DaemonConfig& config);
  // Stops the cell (LEDs off, devices released), after the web view has let go of its frames.
  void dropCell();
  // Hands the running cell's frames, parts and camera to the web view (when it runs).
  void showCellOnWeb(const DaemonConfig& config);
  void watchCell();  // (re-)registers the current cell's result fd with the loop
  void lockMemory();
  bool startServices();
  void mainLoop();
  void shutdown();
  void onSignal();
  void onCellResults();
  void onPlcCommands();

  // daemon_commands.cpp
  void registerCommands();
  nlohmann::json statusJson() const;
  void startControlCycle(ClientId client, const RequestArgs& args, bool snapshot);
  void selectPart(ClientId client, const RequestArgs& args);
  // daemon_calibration.cpp
  bool calibrating() const { return calib_ && (calib_->active() || calib_->busy() || capture_); }
  void handleCalibrate(ClientId client, const nlohmann::json& req);
  void onCalibrationImage(const CycleResult& r);
  void onCalibrationDone();

  // daemon_cycles.cpp
  // A first look whose result asked for a second (the robot link's LOOK continues it).
  struct FirstLook {
    std::uint16_t job = 0;
    std::uint64_t cycle = 0;
    Eigen::Isometry3d base_T_flange = Eigen::Isometry3d::Identity();
  };
  // `first`: the cycle is a second look fused with that first look.
  std::optional<std::uint64_t> startCycle(CycleOrigin origin, std::uint16_t job, std::uint16_t recipe,
                                          std::uint16_t mode, bool snapshot, const FirstLook* first = nullptr);
  void onPlcCommand(const motion::PlcCommand& cmd);
  // NEXT (already published by the Modbus server): the report follows with that pick.
  void onNextPick(const motion::PlcCommand& cmd);
  // PICK_RESULT: counted, logged, and a failed pick's frame set saved (snapshots.on_failed_pick).
  void onPickResult(const motion::PlcCommand& cmd);
  // A PLC or continuous job's result into the robot link's report, with its ranked picks.
  void reportJob(const CycleResult& r);
  // Starts a TRIGGER's (or SAVE_SCENE's) cycle now, or answers the job with ERROR_CODE 7 when the cell cannot take it.
  void startPlcJob(const motion::PlcCommand& cmd);
  // Ends a PLC job that will not run: JOB_ID_ECHO = job, PICK_VALID 0, ERROR_CODE = error.
  void answerJob(std::uint16_t job, std::uint16_t recipe, CycleError error, const char* why);
  // No second look wanted in the report, and none kept.
  void clearLook();
  // Hands a request to the cell and extends the time its threads may be busy with it.
  bool submit(const CycleRequest& r);
  void onResult(const CycleResult& r);
  void afterCycle();
  void publish();
  void updateReady();

  // daemon.cpp
  bool reload(std::string& message);
  void notifyStatus();
  void onTimer();
  // True while every frame-path thread has woken within `grace`, or is allowed to be busy with
  // a request (until that request's deadline + grace).
  bool framePathMoving(Clock::time_point now, std::chrono::milliseconds grace) const;
  int runBenchmark();

  DaemonOptions options_;
  VisionStageFactory vision_;
  FrameSourceFactory source_;
  DaemonConfig config_;
  EventLoop loop_;
  ControlServer control_{loop_};
  RobotLink link_;
  std::unique_ptr<Cell> cell_;
  std::unique_ptr<WebView> webView_;  // web.enabled: what the web server shows
  std::unique_ptr<WebServer> web_;
  int watchedCellFd_ = -1;
  motion::RobotReport report_;
  CycleStats stats_;
  nlohmann::json lastResult_;

  std::optional<CycleRequest> inFlight_;
  std::optional<motion::PlcCommand> pendingPlc_;
  std::vector<Waiter> waiters_;
  std::vector<std::pair<ClientId, nlohmann::json>> reloadWaiters_;  // client, and what to add to the reload's answer
  std::uint64_t nextCycle_ = 1;
  std::uint16_t nextContinuousJob_ = 1;
  std::uint64_t lastJobCycle_ = 0;      // cycle of the job in the robot link's report (0: none)
  std::optional<FirstLook> firstLook_;  // the report's job asks for a second look
  int selectedRecipe_ = 0;
  bool reloadPending_ = false, stopping_ = false, cellOk_ = false;
  Clock::time_point stopRequested_{};

  motion::UniqueFd signalFd_, timerFd_;

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
  std::optional<std::uint16_t> lastPlcPoseSeq_;
  std::uint64_t watchdogUsec_ = 0;
  std::uint64_t lastAcqBeat_ = 0, lastVisionBeat_ = 0;
  Clock::time_point acqMoved_ = Clock::now(), visionMoved_ = Clock::now();
  std::string lastStatus_;
  bool stuckLogged_ = false;
  bool linkDownLogged_ = false;
  bool framesOk_ = true;           // the last cycle captured and ran its vision stage (VISION_OK)
  Clock::time_point busyUntil_{};  // the latest deadline of a request handed to the cell
};

}  // namespace mfcd::daemon
