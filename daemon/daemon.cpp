#include "daemon/daemon.hpp"

#include <fcntl.h>
#include <grp.h>
#include <poll.h>
#include <pwd.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/signalfd.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/timerfd.h>
#include <sys/un.h>
#include <systemd/sd-daemon.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <deque>
#include <iostream>
#include <memory>
#include <vector>

#include <nlohmann/json.hpp>

#include "daemon/calibration.hpp"
#include "daemon/cell.hpp"
#include "daemon/config.hpp"
#include "daemon/cycle_stats.hpp"
#include "daemon/log.hpp"
#include "daemon/report.hpp"
#include "motion/can_publisher.h"
#include "motion/modbus_server.h"

namespace mfcd::daemon {

using nlohmann::json;

namespace {

constexpr const char* kUsage =
    "usage: mfcd [-c FILE] [--data-dir DIR] [-f] [--check-config] [--benchmark N [--benchmark-json FILE]]\n"
    "  -c, --config FILE     configuration (default: the embedded config/sim.yaml, the simulated cell)\n"
    "      --data-dir DIR    searched for relative paths after the config file's directory\n"
    "  -f, --foreground      also log to stderr\n"
    "      --check-config    validate the configuration (and its files) and exit: 0 valid, 2 invalid\n"
    "      --benchmark N     run N cycles back to back (no robot link), print cycle-time percentiles\n"
    "      --benchmark-json FILE   also write them as JSON\n";

double msSince(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

struct ControlClient {
  int fd = -1;
  std::string in;
  uid_t uid = 0;
  std::uint64_t id = 0;  // names the client in calibration jobs answered later
};

struct Waiter {
  int fd;
  std::uint64_t cycle;
  enum class What { Trigger, Snapshot } what;
};

class Daemon {
public:
  Daemon(DaemonOptions options, VisionStageFactory vision) : options_(std::move(options)), vision_(std::move(vision)) {}
  ~Daemon() { shutdownFds(); }
  int run();

private:
  DaemonConfig load() const {
    return options_.configFile.empty() ? loadEmbeddedConfig(options_.dataDir)
                                       : loadConfigFile(options_.configFile, options_.dataDir);
  }
  void startCell(const DaemonConfig& config) {
    auto cell = std::make_unique<Cell>(config, vision_);
    cell->start();
    cell_ = std::move(cell);
    logf(LogLevel::Info, "cell ready: camera %s; vision %s", cell_->sourceDescription().c_str(),
         cell_->visionDescription().c_str());
  }
  void lockMemory();
  void openControlSocket();
  void acceptControlClient();
  void readControlClient(ControlClient& c);
  void handleRequest(ControlClient& c, const std::string& line);
  void reply(int fd, const json& j);
  void closeClient(int fd);
  json statusJson() const;
  void replyToClient(std::uint64_t id, const json& j);
  bool calibrating() const { return calib_ && (calib_->active() || calib_->busy() || capture_); }
  void handleCalibrate(ControlClient& c, const json& req);
  void onCalibrationImage(const CycleResult& r);
  void onCalibrationDone();

  std::optional<std::uint64_t> startCycle(CycleOrigin origin, std::uint16_t job, std::uint16_t recipe, std::uint16_t mode,
                                          bool snapshot);
  void onPlcCommand(const motion::PlcCommand& cmd);
  // Ends a PLC job that will not run: JOB_ID_ECHO = job, PICK_VALID 0, ERROR_CODE = error.
  void answerJob(std::uint16_t job, std::uint16_t recipe, CycleError error, const char* why);
  // Hands a request to the cell and extends the time its threads may be busy with it.
  bool submit(const CycleRequest& r);
  // True while every frame-path thread has woken within `grace`, or is allowed to be busy with
  // a request (until that request's deadline + grace).
  bool framePathMoving(Clock::time_point now, std::chrono::milliseconds grace) const;
  void onResult(const CycleResult& r);
  void afterCycle();
  bool reload(std::string& message);
  void publish();
  void updateReady();
  void notifyStatus();
  void onTimer();
  void shutdownFds();
  int runBenchmark();

  DaemonOptions options_;
  VisionStageFactory vision_;
  DaemonConfig config_;
  std::unique_ptr<Cell> cell_;
  std::unique_ptr<motion::ModbusServer> modbus_;
  std::unique_ptr<motion::CanPublisher> can_;
  motion::RobotReport report_;
  CycleStats stats_;
  json lastResult_;

  std::optional<CycleRequest> inFlight_;
  std::optional<motion::PlcCommand> pendingPlc_;
  std::vector<Waiter> waiters_;
  std::vector<std::pair<int, json>> reloadWaiters_;  // fd, and what to add to the reload's answer
  std::uint64_t nextCycle_ = 1;
  std::uint16_t nextContinuousJob_ = 1;
  int selectedRecipe_ = 0;
  bool reloadPending_ = false, stopping_ = false, cellOk_ = false;
  Clock::time_point stopRequested_{};

  int signalFd_ = -1, timerFd_ = -1, listenFd_ = -1;
  std::vector<ControlClient> clients_;
  std::uint64_t nextClientId_ = 1;

  // mfcd-ctl calibrate: the session runs on the service's worker; a capture in flight waits here
  // for its frame set.
  struct PendingCapture {
    std::uint64_t client = 0;
    std::uint64_t cycle = 0;
    bool check = false;
    std::optional<vision::calib::RobotPose> flange;
    json about;
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
  bool framesOk_ = true;            // the last cycle captured and ran its vision stage (VISION_OK)
  Clock::time_point busyUntil_{};   // the latest deadline of a request handed to the cell
};

void Daemon::lockMemory() {
  if (!config_.lock_memory) return;
  // With MCL_FUTURE every later mapping must fit under RLIMIT_MEMLOCK, or allocations start to fail;
  // only lock when the limit cannot bite (root/CAP_IPC_LOCK or an unlimited limit).
  rlimit lim{};
  getrlimit(RLIMIT_MEMLOCK, &lim);
  if (geteuid() != 0 && lim.rlim_cur != RLIM_INFINITY) {
    logf(LogLevel::Notice, "not locking memory: RLIMIT_MEMLOCK is %llu kB (set LimitMEMLOCK=infinity to allow mlockall)",
         static_cast<unsigned long long>(lim.rlim_cur / 1024));
    return;
  }
  if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0)
    logf(LogLevel::Notice, "mlockall failed (%s); running with pageable memory", std::strerror(errno));
  else
    logf(LogLevel::Info, "memory locked (mlockall)");
}

void Daemon::openControlSocket() {
  const fs::path path = config_.control_socket;
  std::error_code ec;
  fs::create_directories(path.parent_path(), ec);
  listenFd_ = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (listenFd_ < 0) throw std::system_error(errno, std::generic_category(), "control socket");
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::strncpy(addr.sun_path, path.c_str(), sizeof addr.sun_path - 1);
  // A leftover socket file from a crash is removed; a live one means another mfcd is running.
  if (fs::exists(path)) {
    const int probe = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    const bool live = ::connect(probe, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
    ::close(probe);
    if (live) throw std::runtime_error("control socket " + path.string() + ": another mfcd is listening there");
    ::unlink(path.c_str());
  }
  if (::bind(listenFd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0)
    throw std::runtime_error("control socket " + path.string() + ": bind: " + std::strerror(errno) +
                             "; check daemon.control_socket and that its directory is writable");
  ::chmod(path.c_str(), 0660);
  if (::listen(listenFd_, 8) != 0) throw std::system_error(errno, std::generic_category(), "listen " + path.string());
  logf(LogLevel::Info, "control socket %s", path.c_str());
}

bool peerAllowed(int fd, uid_t& uidOut) {
  ucred cred{};
  socklen_t len = sizeof cred;
  if (::getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &cred, &len) != 0) return false;
  uidOut = cred.uid;
  if (cred.uid == 0 || cred.uid == ::geteuid() || cred.gid == ::getegid()) return true;
  // Members of the daemon's group (supplementary groups of the peer's user).
  passwd pw{}, *found = nullptr;
  std::vector<char> buf(16384);
  if (getpwuid_r(cred.uid, &pw, buf.data(), buf.size(), &found) != 0 || !found) return false;
  int n = 64;
  std::vector<gid_t> groups(static_cast<std::size_t>(n));
  if (getgrouplist(pw.pw_name, pw.pw_gid, groups.data(), &n) < 0) return false;
  for (int i = 0; i < n; ++i)
    if (groups[static_cast<std::size_t>(i)] == ::getegid()) return true;
  return false;
}

void Daemon::acceptControlClient() {
  for (;;) {
    const int fd = ::accept4(listenFd_, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
    if (fd < 0) return;
    uid_t uid = 0;
    if (!peerAllowed(fd, uid)) {
      // Logged before the answer: when the client sees the refusal, the record of it exists.
      logf(LogLevel::Notice, "control socket: refused a client with uid %u", static_cast<unsigned>(uid));
      reply(fd, {{"ok", false}, {"error", "permission denied: only root, the daemon's user or members of its group may control mfcd"}});
      ::close(fd);
      continue;
    }
    clients_.push_back({fd, {}, uid, nextClientId_++});
  }
}

void Daemon::reply(int fd, const json& j) {
  // Request text echoed in an error may hold any bytes: invalid UTF-8 is replaced (U+FFFD), as
  // dump() would otherwise throw.
  const std::string line = j.dump(-1, ' ', false, json::error_handler_t::replace) + "\n";
  std::size_t sent = 0;
  // Replies are small; a client that does not read them loses them rather than stall the loop.
  for (int tries = 0; sent < line.size() && tries < 100; ++tries) {
    const ssize_t n = ::send(fd, line.data() + sent, line.size() - sent, MSG_NOSIGNAL | MSG_DONTWAIT);
    if (n > 0) {
      sent += static_cast<std::size_t>(n);
    } else if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      pollfd p{fd, POLLOUT, 0};
      ::poll(&p, 1, 10);
    } else {
      return;
    }
  }
}

void Daemon::closeClient(int fd) {
  for (auto it = clients_.begin(); it != clients_.end(); ++it)
    if (it->fd == fd) {
      ::close(fd);
      clients_.erase(it);
      break;
    }
  std::erase_if(waiters_, [fd](const Waiter& w) { return w.fd == fd; });
  std::erase_if(reloadWaiters_, [fd](const auto& w) { return w.first == fd; });
}

void Daemon::replyToClient(std::uint64_t id, const json& j) {
  for (const auto& c : clients_)
    if (c.id == id) {
      reply(c.fd, j);
      return;
    }
  // The client went away: the job's outcome is in the log and in calibrate status.
}

void Daemon::readControlClient(ControlClient& c) {
  char buf[4096];
  const int fd = c.fd;
  for (;;) {
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK)) {
      closeClient(fd);
      return;
    }
    if (n < 0) break;
    c.in.append(buf, static_cast<std::size_t>(n));
    if (c.in.size() > 65536) {
      reply(fd, {{"ok", false}, {"error", "request line too long"}});
      closeClient(fd);
      return;
    }
  }
  std::size_t nl;
  while ((nl = c.in.find('\n')) != std::string::npos) {
    const std::string line = c.in.substr(0, nl);
    c.in.erase(0, nl + 1);
    if (line.empty()) continue;
    // A request that throws gets an error reply; it never reaches the main loop.
    try {
      handleRequest(c, line);  // may not close c (closing happens only above)
    } catch (const std::exception& e) {
      logf(LogLevel::Warning, "control socket: request failed: %s", e.what());
      reply(fd, {{"ok", false}, {"error", std::string("request failed: ") + e.what()}});
    }
  }
}

json Daemon::statusJson() const {
  json j;
  j["ok"] = true;
  j["pid"] = ::getpid();
  j["config"] = config_.source;
  j["mode"] = toString(config_.mode);
  j["state"] = stopping_        ? "stopping"
               : reloadPending_ ? "reloading"
               : calibrating()  ? "calibrating"
               : inFlight_      ? "busy"
               : cellOk_        ? "ready"
                                : "failed";
  j["ready"] = report_.ready != 0;
  j["vision_ok"] = report_.vision_ok != 0;
  j["error_code"] = report_.error_code;
  j["recipe"] = selectedRecipe_;
  j["cycle_budget_ms"] = config_.cycle_budget_ms;
  if (cell_) {
    j["camera"] = cell_->sourceDescription();
    j["vision"] = cell_->visionDescription();
    j["realtime"] = cell_->realtime();
    json parts = json::array();
    for (const auto& [id, name] : cell_->parts()) parts.push_back({{"obj_id", id}, {"name", name}});
    j["parts"] = parts;
  }
  json recipes = json::array();
  for (const auto& r : config_.recipes) recipes.push_back({{"id", r.id}, {"part", r.part}, {"obj_id", r.obj_id}});
  j["recipes"] = recipes;
  if (modbus_) {
    const auto s = modbus_->stats();
    j["modbus"] = {{"port", modbus_->port()}, {"clients", s.clients_now}, {"requests", s.requests_answered},
                   {"commands", s.commands_queued}, {"exceptions", s.exceptions_sent}};
  }
  if (can_) j["can"] = {{"interface", config_.can.interface}, {"state", motion::to_string(can_->state())}};
  j["cycles"] = stats_.cycles();
  j["overruns"] = stats_.overruns();
  if (calib_) {
    j["calibration"] = calib_->state();
    if (calib_->busy()) j["calibration"]["working"] = calib_->working();
  }
  if (!lastResult_.is_null()) {
    j["last_cycle"] = {{"cycle", lastResult_["cycle"]}, {"total_ms", lastResult_["times_ms"]["total"]},
                       {"overrun", lastResult_["overrun"]}, {"degraded", lastResult_["degraded"]},
                       {"error", lastResult_["error"]}, {"candidates", lastResult_["candidates"].size()}};
  }
  return j;
}

void Daemon::publish() {
  if (modbus_) modbus_->publish(report_);
  if (can_) can_->publish(report_);
}

void Daemon::updateReady() {
  // A calibration session pauses picking: the camera looks at the calibration plate, not the bin.
  const std::uint16_t ready =
      cellOk_ && !inFlight_ && !reloadPending_ && !stopping_ && !calibrating() && config_.mode == RunMode::Triggered;
  const std::uint16_t visionOk = cellOk_ && framesOk_;
  if (ready != report_.ready || visionOk != report_.vision_ok) {
    report_.ready = ready;
    report_.vision_ok = visionOk;
    publish();
  }
}

std::optional<std::uint64_t> Daemon::startCycle(CycleOrigin origin, std::uint16_t job, std::uint16_t recipe, std::uint16_t mode,
                                                bool snapshot) {
  if (!cell_ || inFlight_) return std::nullopt;
  CycleRequest r;
  r.origin = origin;
  r.cycle_id = nextCycle_++;
  r.job_id = job;
  r.recipe_id = recipe;
  r.mode = mode;
  r.snapshot = snapshot;
  r.trigger = Clock::now();
  // The pipeline gets the budget minus a reserve for pick choice and publishing.
  const auto budget = std::chrono::milliseconds(config_.cycle_budget_ms);
  r.deadline = r.trigger + budget - std::min<std::chrono::milliseconds>(std::chrono::milliseconds(50), budget / 10);
  const RecipeConfig* rc = config_.recipe(recipe);
  if (!rc) {
    CycleResult fail;
    fail.request = r;
    fail.error = CycleError::UnknownRecipe;
    const std::string msg = "recipe " + std::to_string(recipe) + " is not in the configuration (" + config_.source + ")";
    copyMessage(fail.message, sizeof fail.message, msg.c_str());
    onResult(fail);
    return r.cycle_id;
  }
  r.obj_id = rc->obj_id;
  if (!submit(r)) return std::nullopt;
  inFlight_ = r;
  updateReady();
  return r.cycle_id;
}

void Daemon::onPlcCommand(const motion::PlcCommand& cmd) {
  if (cmd.kind == motion::PlcCommand::Kind::Reset) {
    logf(LogLevel::Info, "PLC: RESET (error code %u cleared)", report_.error_code);
    report_.error_code = 0;
    pendingPlc_.reset();
    publish();
    return;
  }
  logf(LogLevel::Debug, "PLC: TRIGGER job %u recipe %u mode %u", cmd.job_id, cmd.recipe_id, cmd.mode);
  if (calibrating()) {
    // READY is clear during a session, so only a trigger racing the session's start gets here:
    // it is answered at once with ERROR_CODE 6 rather than left pending.
    logf(LogLevel::Warning, "PLC: TRIGGER job %u refused: a calibration session is running", cmd.job_id);
    report_.job_id = cmd.job_id;
    report_.recipe_id = cmd.recipe_id;
    report_.error_code = static_cast<std::uint16_t>(CycleError::Calibrating);
    report_.pick_valid = 0;
    publish();
    return;
  }
  if (inFlight_ || reloadPending_) {
    pendingPlc_ = cmd;  // accepted by the server during a local cycle: runs right after it
    return;
  }
  if (!startCycle(CycleOrigin::Plc, cmd.job_id, cmd.recipe_id, cmd.mode, false))
    answerJob(cmd.job_id, cmd.recipe_id, CycleError::Unavailable, cell_ ? "the cell's request queue is full" : "no cell is running");
}

void Daemon::answerJob(std::uint16_t job, std::uint16_t recipe, CycleError error, const char* why) {
  logf(LogLevel::Error, "PLC: job %u (recipe %u) not run: %s; answered with error code %u", job, recipe, why,
       static_cast<unsigned>(error));
  report_.job_id = job;
  report_.recipe_id = recipe;
  report_.error_code = static_cast<std::uint16_t>(error);
  report_.pick_valid = 0;
  report_.candidate_count = 0;
  report_.candidate_index = 0;
  report_.objects_remaining = 0;
  report_.pick = motion::PickPose{};
  report_.score = 0.0f;
  publish();
}

bool Daemon::submit(const CycleRequest& r) {
  if (!cell_ || !cell_->submit(r)) return false;
  const auto budget = std::chrono::milliseconds(config_.cycle_budget_ms);
  busyUntil_ = std::max(busyUntil_, r.kind == CycleRequest::Kind::Capture ? r.deadline : Clock::now() + budget);
  return true;
}

void Daemon::onResult(const CycleResult& r) {
  if (r.kind == CycleResult::Kind::CalibrationImage) {
    onCalibrationImage(r);
    return;
  }
  if (r.kind == CycleResult::Kind::SnapshotSaved) {
    if (r.snapshot_dir[0])
      logf(LogLevel::Info, "snapshot of cycle %llu saved in %s", static_cast<unsigned long long>(r.request.cycle_id), r.snapshot_dir);
    else
      logf(LogLevel::Warning, "snapshot of cycle %llu failed: %s", static_cast<unsigned long long>(r.request.cycle_id), r.message);
    for (auto it = waiters_.begin(); it != waiters_.end();) {
      if (it->what == Waiter::What::Snapshot && it->cycle == r.request.cycle_id) {
        if (r.snapshot_dir[0])
          reply(it->fd, {{"ok", true}, {"snapshot", r.snapshot_dir}, {"result", resultJson(r, config_)}});
        else
          reply(it->fd, {{"ok", false}, {"error", r.message}});
        it = waiters_.erase(it);
      } else {
        ++it;
      }
    }
    return;
  }
  if (inFlight_ && inFlight_->cycle_id == r.request.cycle_id) inFlight_.reset();
  if (r.error == CycleError::Capture || r.error == CycleError::Vision) {
    if (framesOk_) logf(LogLevel::Error, "VISION_OK cleared: %s; the next cycle retries", r.message);
    framesOk_ = false;
  } else if (r.error != CycleError::UnknownRecipe) {  // captured and processed: camera and vision work
    if (!framesOk_) logf(LogLevel::Notice, "VISION_OK set again: cycle %llu captured and processed its frames",
                         static_cast<unsigned long long>(r.request.cycle_id));
    framesOk_ = true;
  }
  const bool overrun = stats_.add(r, config_.cycle_budget_ms);
  lastResult_ = resultJson(r, config_);
  const unsigned long long id = r.request.cycle_id;
  if (r.error != CycleError::None)
    logf(LogLevel::Error, "cycle %llu (%s job %u recipe %u): error %u: %s", id, toString(r.request.origin), r.request.job_id,
         r.request.recipe_id, static_cast<unsigned>(r.error), r.message);
  else if (r.chosen >= 0) {
    const auto& p = r.candidates[static_cast<std::size_t>(r.chosen)].base;
    logf(LogLevel::Info, "cycle %llu (%s job %u recipe %u): pick obj %d at %.1f %.1f %.1f / %.1f %.1f %.1f score %.3f, %d found, %.0f ms%s",
         id, toString(r.request.origin), r.request.job_id, r.request.recipe_id, r.candidates[static_cast<std::size_t>(r.chosen)].obj_id,
         p.x_mm, p.y_mm, p.z_mm, p.rx_deg, p.ry_deg, p.rz_deg, r.candidates[static_cast<std::size_t>(r.chosen)].score,
         r.candidate_count, r.total_ms, r.degraded ? " (degraded)" : "");
  } else {
    logf(LogLevel::Notice, "cycle %llu (%s job %u recipe %u): no pick, %d found, %.0f ms", id, toString(r.request.origin),
         r.request.job_id, r.request.recipe_id, r.candidate_count, r.total_ms);
  }
  if (overrun)
    logf(LogLevel::Warning, "cycle %llu overran its budget: %.0f ms > %d ms (capture %.0f, vision %.0f; %s)", id, r.total_ms,
         config_.cycle_budget_ms, r.capture_ms, r.vision_ms, r.degraded ? "degraded result" : "full result");
  if (!r.leds_off) logf(LogLevel::Error, "cycle %llu: LEDs were not all off after the capture", id);

  // Robot link: PLC jobs and continuous cycles are published; control-socket cycles are not (they
  // would change JOB_ID_ECHO under the PLC's handshake).
  if (r.request.origin == CycleOrigin::Plc || r.request.origin == CycleOrigin::Continuous) {
    report_.job_id = r.request.job_id;
    report_.recipe_id = r.request.recipe_id;
    report_.error_code = static_cast<std::uint16_t>(r.error);
    report_.objects_remaining = static_cast<std::uint16_t>(r.candidate_count);
    report_.cycle_time_ms = static_cast<std::uint16_t>(std::min(65535.0, r.total_ms));
    report_.candidate_count = static_cast<std::uint16_t>(r.candidate_count);
    report_.candidate_index = static_cast<std::uint16_t>(std::max(0, r.chosen));
    report_.pick_valid = r.chosen >= 0;
    report_.pick = r.chosen >= 0 ? r.candidates[static_cast<std::size_t>(r.chosen)].base : motion::PickPose{};
    report_.score = r.chosen >= 0 ? r.candidates[static_cast<std::size_t>(r.chosen)].score : 0.0f;
  }
  report_.ready = 0;  // recomputed below, in the same publish
  updateReady();
  publish();

  // The simulated robot takes the part it was given.
  if (r.chosen >= 0 && cell_) {
    CycleRequest take;
    take.kind = CycleRequest::Kind::RemovePicked;
    take.picked_t_cam_mm = r.candidates[static_cast<std::size_t>(r.chosen)].t_cam_mm;
    submit(take);
  } else if (r.error == CycleError::None && r.candidate_count == 0 && r.truth.count > 0 && cell_) {
    // Simulated cell: vision sees nothing in a bin that still holds parts (all unrecognised); like
    // an operator would, tip in a fresh bin so the cell does not stall on one scene.
    CycleRequest refill;
    refill.kind = CycleRequest::Kind::Refill;
    submit(refill);
  }
  for (auto it = waiters_.begin(); it != waiters_.end();) {
    if (it->what == Waiter::What::Trigger && it->cycle == r.request.cycle_id) {
      json j = {{"ok", r.error == CycleError::None}, {"result", lastResult_}};
      if (r.error != CycleError::None) j["error"] = r.message;
      reply(it->fd, j);
      it = waiters_.erase(it);
    } else {
      ++it;
    }
  }
  notifyStatus();
}

void Daemon::afterCycle() {
  if (inFlight_) return;
  if (stopping_) return;
  if (reloadPending_) {
    std::string message;
    const bool ok = reload(message);
    for (auto& [fd, base] : reloadWaiters_) {
      json j = base.is_object() ? base : json::object();
      if (ok) {
        j["ok"] = j.value("ok", true);
        j["reload"] = message;
      } else {
        j["ok"] = false;
        j["error"] = j.contains("message") ? j.value("message", "") + "; but " + message : message;
      }
      if (!base.is_object()) j["message"] = message;
      reply(fd, j);
    }
    reloadWaiters_.clear();
    reloadPending_ = false;
    updateReady();
    notifyStatus();
  }
  if (pendingPlc_) {
    const auto cmd = *pendingPlc_;
    pendingPlc_.reset();
    if (!startCycle(CycleOrigin::Plc, cmd.job_id, cmd.recipe_id, cmd.mode, false))
      answerJob(cmd.job_id, cmd.recipe_id, CycleError::Unavailable, cell_ ? "the cell's request queue is full" : "no cell is running");
    return;
  }
  if (config_.mode == RunMode::Continuous && cellOk_ && !calibrating()) {
    const std::uint16_t job = nextContinuousJob_;
    nextContinuousJob_ = static_cast<std::uint16_t>(nextContinuousJob_ == 65535 ? 1 : nextContinuousJob_ + 1);
    startCycle(CycleOrigin::Continuous, job, static_cast<std::uint16_t>(selectedRecipe_), 0, false);
  }
}

bool Daemon::reload(std::string& message) {
  sd_notify(0, "RELOADING=1\nSTATUS=reloading configuration");
  DaemonConfig next;
  try {
    next = load();
  } catch (const std::exception& e) {
    message = std::string("reload refused, keeping the running configuration: ") + e.what();
    logf(LogLevel::Error, "%s", message.c_str());
    sd_notify(0, "READY=1");
    return false;
  }
  if (next.modbus.bind_address != config_.modbus.bind_address || next.modbus.port != config_.modbus.port ||
      next.modbus.word_order != config_.modbus.word_order || next.modbus.max_clients != config_.modbus.max_clients ||
      next.modbus.frame_timeout != config_.modbus.frame_timeout || next.modbus.idle_timeout != config_.modbus.idle_timeout ||
      next.modbus.allow_list != config_.modbus.allow_list)
    logf(LogLevel::Warning, "reload: modbus.* changed; the Modbus server keeps its settings until mfcd restarts "
         "(reloading keeps PLC connections open)");
  if (next.control_socket != config_.control_socket)
    logf(LogLevel::Warning, "reload: daemon.control_socket changed; it takes effect at the next start");
  next.modbus = config_.modbus;
  next.control_socket = config_.control_socket;
  cell_.reset();  // stops the threads, LEDs off, releases the devices for the new cell
  try {
    startCell(next);
    cellOk_ = true;
  } catch (const std::exception& e) {
    message = std::string("reload failed, restored the running configuration: ") + e.what();
    logf(LogLevel::Error, "%s", message.c_str());
    try {
      startCell(config_);
      cellOk_ = true;
    } catch (const std::exception& e2) {
      cellOk_ = false;
      logf(LogLevel::Error, "restoring the previous cell failed too: %s", e2.what());
    }
    sd_notify(0, "READY=1");
    return false;
  }
  if (next.can_enabled != config_.can_enabled || next.can.interface != config_.can.interface ||
      next.can.id_base != config_.can.id_base) {
    can_.reset();
    if (next.can_enabled) {
      can_ = std::make_unique<motion::CanPublisher>(next.can);
      can_->start();
    }
  }
  config_ = std::move(next);
  logSetLevel(config_.log_level);
  if (!config_.recipe(selectedRecipe_)) selectedRecipe_ = config_.default_recipe;
  message = "reloaded " + config_.source;
  logf(LogLevel::Info, "%s", message.c_str());
  sd_notify(0, "READY=1");
  return true;
}

void Daemon::notifyStatus() {
  char status[256];
  std::snprintf(status, sizeof status, "STATUS=%s, %s mode, %llu cycles, %llu overruns, p50 %.0f ms", 
                stopping_ ? "stopping" : inFlight_ ? "busy" : cellOk_ ? "ready" : "camera/vision failed",
                toString(config_.mode), static_cast<unsigned long long>(stats_.cycles()),
                static_cast<unsigned long long>(stats_.overruns()), stats_.percentileMs(50));
  if (lastStatus_ != status) {
    lastStatus_ = status;
    sd_notify(0, status);
  }
}

bool Daemon::framePathMoving(Clock::time_point now, std::chrono::milliseconds grace) const {
  if (!cell_) return true;
  const bool busy = now < busyUntil_ + grace;
  return (busy || now - acqMoved_ < grace) && (busy || now - visionMoved_ < grace);
}

// Every tick (at most 500 ms apart): liveness for the PLC and for systemd. HEARTBEAT gets a
// lease of one second while the frame path moves within kHeartbeatGrace (an idle thread wakes
// every 200 ms), so a hang of the main thread (no tick), of a frame-path thread or of a cycle
// past its deadline freezes HEARTBEAT within ~2.5 s. The systemd watchdog, which restarts mfcd,
// waits longer (stall) and is also withheld once the robot link's thread has died.
void Daemon::onTimer() {
  constexpr std::chrono::milliseconds kHeartbeatGrace{1000}, kHeartbeatLease{1000};
  std::uint64_t expirations;
  [[maybe_unused]] ssize_t n = ::read(timerFd_, &expirations, sizeof expirations);
  const auto now = Clock::now();
  if (cell_) {
    if (cell_->acquisitionHeartbeat() != lastAcqBeat_) lastAcqBeat_ = cell_->acquisitionHeartbeat(), acqMoved_ = now;
    if (cell_->visionHeartbeat() != lastVisionBeat_) lastVisionBeat_ = cell_->visionHeartbeat(), visionMoved_ = now;
  }
  const bool linkUp = !modbus_ || modbus_->serving();
  if (framePathMoving(now, kHeartbeatGrace)) {
    if (modbus_) modbus_->lease_health(now + kHeartbeatLease);
    if (can_) can_->lease_health(now + kHeartbeatLease);
  }
  if (!linkUp && !linkDownLogged_) {
    logf(LogLevel::Error, "the Modbus server thread has ended; withholding the systemd watchdog so mfcd is restarted");
    linkDownLogged_ = true;
  }
  // A thread is stuck when it has not woken for longer than any cycle may take.
  const auto stall = std::max<std::chrono::milliseconds>(std::chrono::seconds(5), 3 * std::chrono::milliseconds(config_.cycle_budget_ms));
  const bool moving = framePathMoving(now, stall);
  if (watchdogUsec_ && moving && linkUp) sd_notify(0, "WATCHDOG=1");
  if (!moving && !stuckLogged_) {
    logf(LogLevel::Error, "a frame-path thread has not moved for %lld ms; withholding the systemd watchdog",
         static_cast<long long>(stall.count()));
    stuckLogged_ = true;
  }
  if (moving) stuckLogged_ = false;
  notifyStatus();
}

void Daemon::handleRequest(ControlClient& c, const std::string& line) {
  json req;
  try {
    req = json::parse(line);
  } catch (const std::exception& e) {
    reply(c.fd, {{"ok", false}, {"error", std::string("bad request (one JSON object per line): ") + e.what()}});
    return;
  }
  const std::string cmd = req.is_object() && req.contains("cmd") && req["cmd"].is_string() ? req["cmd"].get<std::string>() : "";
  if (cmd == "status") {
    reply(c.fd, statusJson());
  } else if (cmd == "stats") {
    json j = stats_.toJson();
    j["ok"] = true;
    j["budget_ms"] = config_.cycle_budget_ms;
    reply(c.fd, j);
  } else if (cmd == "last") {
    reply(c.fd, {{"ok", !lastResult_.is_null()}, {"result", lastResult_}});
  } else if (cmd == "trigger" || cmd == "snapshot") {
    const int recipe = req.contains("recipe") && req["recipe"].is_number_integer() ? req["recipe"].get<int>() : selectedRecipe_;
    if (recipe < 0 || recipe > 65535) {
      reply(c.fd, {{"ok", false}, {"error", "recipe must be 0..65535"}});
      return;
    }
    if (calibrating()) {
      reply(c.fd, {{"ok", false}, {"error", "busy: a calibration session is running (picking is paused; "
                                            "mfcd-ctl calibrate apply or abort ends it)"}});
      return;
    }
    if (stopping_ || reloadPending_ || inFlight_ || config_.mode == RunMode::Continuous || !cellOk_) {
      reply(c.fd, {{"ok", false}, {"error", config_.mode == RunMode::Continuous ? "busy: continuous mode runs cycles by itself"
                                                                                 : "busy: a cycle is running or mfcd is not ready"}});
      return;
    }
    const bool snap = cmd == "snapshot";
    const auto id = startCycle(CycleOrigin::Control, 0, static_cast<std::uint16_t>(recipe), 0, snap);
    if (!id) {
      reply(c.fd, {{"ok", false}, {"error", "busy"}});
      return;
    }
    // Replied to when the cycle (or its snapshot) is done; an unknown recipe has answered already.
    if (!lastResult_.is_null() && lastResult_["cycle"] == *id && lastResult_["error_code"] == static_cast<int>(CycleError::UnknownRecipe)) {
      reply(c.fd, {{"ok", false}, {"error", lastResult_.value("message", "unknown recipe")}, {"result", lastResult_}});
      return;
    }
    waiters_.push_back({c.fd, *id, snap ? Waiter::What::Snapshot : Waiter::What::Trigger});
  } else if (cmd == "part") {
    if (!req.contains("recipe") || !req["recipe"].is_number_integer() || !config_.recipe(req["recipe"].get<int>())) {
      reply(c.fd, {{"ok", false}, {"error", "part: give {\"recipe\": id} with an id from the configuration's recipes"}});
      return;
    }
    selectedRecipe_ = req["recipe"].get<int>();
    logf(LogLevel::Info, "recipe %d (%s) selected by the control socket", selectedRecipe_, config_.recipe(selectedRecipe_)->part.c_str());
    reply(c.fd, {{"ok", true}, {"recipe", selectedRecipe_}, {"part", config_.recipe(selectedRecipe_)->part}});
  } else if (cmd == "reload") {
    reloadPending_ = true;
    reloadWaiters_.emplace_back(c.fd, json());
    updateReady();
    afterCycle();
  } else if (cmd == "calibrate") {
    handleCalibrate(c, req);
  } else {
    reply(c.fd, {{"ok", false}, {"error", "unknown command '" + cmd + "' (status, stats, last, trigger, snapshot, part, reload, calibrate)"}});
  }
}

void Daemon::handleCalibrate(ControlClient& c, const json& req) {
  std::string action;
  const auto refuse = [&](const std::string& why) {
    reply(c.fd, {{"ok", false}, {"error", "calibrate" + (action.empty() ? std::string() : " " + action) + ": " + why}});
  };
  try {
    action = req.contains("action") && req["action"].is_string() ? req["action"].get<std::string>() : "";
    if (action == "status") {
      json j = {{"ok", true}, {"session", calib_->state()}, {"picking", calibrating() ? "paused" : "running"}};
      if (calib_->busy()) j["working"] = calib_->working();
      if (capture_) j["capturing"] = true;
      j["camera_file"] = config_.camera.model.string();
      reply(c.fd, j);
      return;
    }
    if (action == "abort") {  // also while a job runs: it is queued behind it
      if (capture_) return refuse("a capture is in flight; abort again when it has answered");
      calib_->abort(c.id);
      updateReady();
      return;
    }
    if (calib_->busy()) return refuse("busy: still working on '" + calib_->working() + "'; try again when it has answered");
    if (capture_) return refuse("busy: a capture is in flight");
    if (action == "start") {
      if (calib_->active())
        return refuse("a " + calib_->state().value("kind", "") + " session is already running (mfcd-ctl calibrate abort ends it)");
      if (stopping_ || reloadPending_ || !cellOk_) return refuse("mfcd is not ready (stopping, reloading, or the cell failed)");
      if (inFlight_ || pendingPlc_) return refuse("busy: a pick cycle is running; try again when it is done");
      const std::string kind = req.contains("kind") && req["kind"].is_string() ? req["kind"].get<std::string>() : "";
      if (kind != "intrinsics" && kind != "hand-eye") return refuse("kind must be intrinsics or hand-eye");
      auto mode = vision::calib::HandEyeMode::eye_to_hand;
      if (kind == "hand-eye" && req.contains("mode")) {
        if (!req["mode"].is_string()) return refuse("mode must be eye-in-hand or eye-to-hand");
        mode = vision::calib::parse_hand_eye_mode(req["mode"].get<std::string>());
      }
      lastPlcPoseSeq_.reset();
      calib_->start(c.id, kind == "intrinsics" ? CalibrationService::Kind::Intrinsics : CalibrationService::Kind::HandEye, mode,
                    config_.camera.model, config_.calibration);
      updateReady();  // READY drops for the session
      return;
    }
    if (action == "capture" || action == "check") {
      const bool check = action == "check";
      if (!calib_->active()) return refuse("no calibration session (mfcd-ctl calibrate intrinsics start, or hand-eye start)");
      if (check && (!calib_->handEye() || !calib_->computed()))
        return refuse("check needs a computed hand-eye calibration (calibrate compute first)");
      if (inFlight_ || reloadPending_ || stopping_ || !cellOk_ || !cell_)
        return refuse("busy: a cycle or reload is running, or the cell failed");
      const bool fromPlc = req.value("pose_from_plc", false);
      if (fromPlc && req.contains("pose")) return refuse("give --pose or --pose-from-plc, not both");
      std::optional<vision::calib::RobotPose> flange;
      json about = json::object();
      if (req.contains("pose")) {
        flange = poseFromJson(req["pose"], "--pose");
        about["pose_source"] = "command line";
      } else if (fromPlc) {
        const motion::RobotPoseReading p = modbus_->robot_pose();
        if (p.writes == 0)
          return refuse("--pose-from-plc: the PLC has not written the robot pose block (registers 36..49, "
                        "docs/register-map.md)");
        if (p.valid == 0) return refuse("--pose-from-plc: ROBOT_POSE_VALID (register 48) is 0: the PLC marks the pose as not current");
        if (lastPlcPoseSeq_ && *lastPlcPoseSeq_ == p.sequence)
          return refuse("--pose-from-plc: ROBOT_POSE_SEQ (register 49) is still " + std::to_string(p.sequence) +
                        " as for the previous view: the PLC has not written a new pose");
        flange = vision::calib::RobotPose{p.x_mm, p.y_mm, p.z_mm, p.rx_deg, p.ry_deg, p.rz_deg};
        about["pose_source"] = "plc";
        about["pose_sequence"] = p.sequence;
      }
      if (flange)
        about["pose"] = {flange->x_mm, flange->y_mm, flange->z_mm, flange->rx_deg, flange->ry_deg, flange->rz_deg};
      if (calib_->handEye() && !flange)
        return refuse("a hand-eye view needs the robot flange pose: --pose x,y,z,rx,ry,rz or --pose-from-plc");
      // The simulated cell stages the plate; a real cell ignores this (the plate is really there).
      PlateRequest plate;
      if (req.contains("sim_plate_pose")) {
        const auto p = poseFromJson(req["sim_plate_pose"], "--sim-plate-pose");
        plate.kind = PlateRequest::Kind::Camera;
        plate.pose = {p.x_mm, p.y_mm, p.z_mm, p.rx_deg, p.ry_deg, p.rz_deg};
      } else if (calib_->handEye() && flange) {
        plate.kind = calib_->eyeInHand() ? PlateRequest::Kind::EyeInHand : PlateRequest::Kind::EyeToHand;
        plate.pose = {flange->x_mm, flange->y_mm, flange->z_mm, flange->rx_deg, flange->ry_deg, flange->rz_deg};
      }
      CycleRequest r;
      r.kind = CycleRequest::Kind::CalibrationCapture;
      r.origin = CycleOrigin::Control;
      r.cycle_id = nextCycle_++;
      r.trigger = Clock::now();
      r.deadline = r.trigger + std::chrono::milliseconds(config_.cycle_budget_ms);
      r.plate = plate;
      if (!submit(r)) return refuse("busy: the acquisition queue is full");
      inFlight_ = r;
      capture_ = PendingCapture{c.id, r.cycle_id, check, flange, std::move(about)};
      updateReady();
      return;
    }
    if (action == "compute") {
      if (!calib_->active()) return refuse("no calibration session");
      calib_->compute(c.id);
      return;
    }
    if (action == "apply") {
      if (!calib_->active()) return refuse("no calibration session");
      if (!calib_->computed()) return refuse("nothing computed yet (calibrate compute, then apply)");
      if (!req.value("confirm", false))
        return refuse("this writes " + config_.camera.model.string() + ": confirm with --yes (mfcd-ctl asks y/N on a terminal)");
      calib_->apply(c.id);
      return;
    }
    if (action == "rollback") {
      if (calib_->active()) return refuse("a calibration session is running: apply or abort it first");
      if (!req.value("confirm", false))
        return refuse("this overwrites " + config_.camera.model.string() + " with its .previous copy: confirm with --yes");
      calib_->rollback(c.id, config_.camera.model);
      return;
    }
    refuse("unknown action '" + action + "' (start, capture, compute, check, apply, rollback, abort, status)");
  } catch (const std::exception& e) {  // bad field types, bad poses, unknown hand-eye mode
    refuse(e.what());
  }
}

void Daemon::onCalibrationImage(const CycleResult& r) {
  inFlight_.reset();
  if (!capture_ || capture_->cycle != r.request.cycle_id) {
    logf(LogLevel::Warning, "calibration image of cycle %llu arrived with no capture waiting for it",
         static_cast<unsigned long long>(r.request.cycle_id));
    updateReady();
    return;
  }
  PendingCapture pc = std::move(*capture_);
  capture_.reset();
  if (!r.leds_off) logf(LogLevel::Error, "calibration capture %llu: LEDs were not all off after the capture",
                        static_cast<unsigned long long>(r.request.cycle_id));
  if (r.error != CycleError::None) {
    json j = pc.about;
    j["ok"] = false;
    j["error"] = std::string("capture failed: ") + r.message;
    replyToClient(pc.client, j);
    updateReady();
    return;
  }
  if (pc.about.contains("pose_sequence")) lastPlcPoseSeq_ = pc.about["pose_sequence"].get<std::uint16_t>();
  pc.about["capture_ms"] = r.capture_ms;
  cv::Mat1b image = cell_->calibrationImage().clone();  // the cell's buffer is reused by the next capture
  if (pc.check)
    calib_->check(pc.client, std::move(image), *pc.flange, std::move(pc.about));
  else
    calib_->addView(pc.client, std::move(image), pc.flange, std::move(pc.about));
  updateReady();
}

void Daemon::onCalibrationDone() {
  for (auto& d : calib_->takeDone()) {
    if (d.reload) {
      // The camera file changed: the cell is rebuilt on it through the ordinary reload path;
      // the client is answered when that is done.
      const auto it = std::find_if(clients_.begin(), clients_.end(), [&](const ControlClient& c) { return c.id == d.client; });
      if (it != clients_.end()) reloadWaiters_.emplace_back(it->fd, d.reply);
      logf(LogLevel::Info, "calibration: reloading so the cell uses the new camera file");
      reloadPending_ = true;
    } else {
      replyToClient(d.client, d.reply);
    }
  }
  updateReady();
  notifyStatus();
}

void Daemon::shutdownFds() {
  for (auto& c : clients_) ::close(c.fd);
  clients_.clear();
  if (listenFd_ >= 0) {
    ::close(listenFd_);
    ::unlink(config_.control_socket.c_str());
    listenFd_ = -1;
  }
  if (timerFd_ >= 0) ::close(timerFd_), timerFd_ = -1;
  if (signalFd_ >= 0) ::close(signalFd_), signalFd_ = -1;
}

int Daemon::runBenchmark() {
  const int n = options_.benchmarkCycles;
  for (int i = 0; i < n; ++i) {
    startCycle(CycleOrigin::Benchmark, 0, static_cast<std::uint16_t>(config_.default_recipe), 0, false);
    for (;;) {
      pollfd p{cell_->resultFd(), POLLIN, 0};
      ::poll(&p, 1, 1000);
      bool done = false;
      while (CycleResult* r = cell_->beginResult()) {
        const CycleResult copy = *r;
        cell_->endResult();
        if (copy.kind == CycleResult::Kind::Cycle) {
          onResult(copy);
          done = true;
        }
      }
      if (done) break;
    }
  }
  json j = stats_.toJson();
  j["budget_ms"] = config_.cycle_budget_ms;
  j["camera"] = cell_->sourceDescription();
  j["vision"] = cell_->visionDescription();
  std::printf("%s\n", j.dump(2, ' ', false, json::error_handler_t::replace).c_str());
  std::printf("\n| stage | p50 ms | p90 ms | p99 ms | max ms |\n|---|---|---|---|---|\n");
  for (const char* stage : {"total", "capture", "vision"})
    std::printf("| %s | %.1f | %.1f | %.1f | %.1f |\n", stage, stats_.percentileMs(stage, 50), stats_.percentileMs(stage, 90),
                stats_.percentileMs(stage, 99), stats_.percentileMs(stage, 100));
  std::printf("\n%llu cycles, %llu overruns of %d ms, %llu degraded, %llu errors, %llu picks\n",
              static_cast<unsigned long long>(stats_.cycles()), static_cast<unsigned long long>(stats_.overruns()),
              config_.cycle_budget_ms, static_cast<unsigned long long>(stats_.degraded()),
              static_cast<unsigned long long>(stats_.errors()), static_cast<unsigned long long>(stats_.picks()));
  if (!options_.benchmarkJson.empty()) {
    FILE* f = std::fopen(options_.benchmarkJson.c_str(), "w");
    if (!f) {
      logf(LogLevel::Error, "cannot write %s: %s", options_.benchmarkJson.c_str(), std::strerror(errno));
      return 1;
    }
    std::fprintf(f, "%s\n", j.dump(2, ' ', false, json::error_handler_t::replace).c_str());
    std::fclose(f);
  }
  cell_.reset();
  return 0;
}

int Daemon::run() {
  logOpen("mfcd", options_.foreground || options_.benchmarkCycles > 0, LogLevel::Info);
  try {
    config_ = load();
  } catch (const std::exception& e) {
    logf(LogLevel::Error, "configuration: %s", e.what());
    return 2;
  }
  logSetLevel(config_.log_level);
  if (options_.checkConfig) {
    std::printf("%s: valid\n", config_.source.c_str());
    return 0;
  }
  selectedRecipe_ = config_.default_recipe;

  // Signals are taken through a signalfd: block them before any thread starts so all inherit it.
  sigset_t mask;
  sigemptyset(&mask);
  sigaddset(&mask, SIGTERM);
  sigaddset(&mask, SIGINT);
  sigaddset(&mask, SIGHUP);
  pthread_sigmask(SIG_BLOCK, &mask, nullptr);
  ::signal(SIGPIPE, SIG_IGN);

  try {
    startCell(config_);
    cellOk_ = true;
  } catch (const std::exception& e) {
    logf(LogLevel::Error, "starting the cell: %s", e.what());
    return 1;
  }
  lockMemory();
  if (options_.benchmarkCycles > 0) return runBenchmark();

  try {
    modbus_ = std::make_unique<motion::ModbusServer>(config_.modbus);
    modbus_->start();
    logf(LogLevel::Info, "Modbus/TCP on %s port %u", config_.modbus.bind_address.c_str(), modbus_->port());
    if (config_.can_enabled) {
      can_ = std::make_unique<motion::CanPublisher>(config_.can);
      can_->start();
    }
    openControlSocket();
    calib_ = std::make_unique<CalibrationService>();
  } catch (const std::exception& e) {
    logf(LogLevel::Error, "%s", e.what());
    cell_.reset();
    return 1;
  }
  signalFd_ = ::signalfd(-1, &mask, SFD_CLOEXEC | SFD_NONBLOCK);
  timerFd_ = ::timerfd_create(CLOCK_MONOTONIC, TFD_CLOEXEC | TFD_NONBLOCK);
  if (sd_watchdog_enabled(0, &watchdogUsec_) <= 0) watchdogUsec_ = 0;
  // At most 500 ms: the HEARTBEAT lease (onTimer) and half the systemd watchdog interval.
  const std::uint64_t tickUs = watchdogUsec_ ? std::clamp<std::uint64_t>(watchdogUsec_ / 2, 1000, 500'000) : 500'000;
  itimerspec its{};
  its.it_interval.tv_sec = static_cast<time_t>(tickUs / 1'000'000);
  its.it_interval.tv_nsec = static_cast<long>((tickUs % 1'000'000) * 1000);
  its.it_value = its.it_interval;
  ::timerfd_settime(timerFd_, 0, &its, nullptr);

  report_.vision_ok = 1;
  modbus_->lease_health(Clock::now() + std::chrono::seconds(1));
  if (can_) can_->lease_health(Clock::now() + std::chrono::seconds(1));
  updateReady();
  publish();
  sd_notify(0, "READY=1");
  notifyStatus();
  logf(LogLevel::Notice, "mfcd ready (%s, %s mode, budget %d ms)", config_.source.c_str(), toString(config_.mode),
       config_.cycle_budget_ms);
  afterCycle();  // continuous mode starts its first cycle

  std::vector<pollfd> fds;
  for (;;) {
    if (stopping_) {
      // Finish the cycle in flight (bounded by its deadline); abandon it if it outlives the grace.
      const bool graceOver = msSince(stopRequested_) > config_.cycle_budget_ms + 2000;
      if (!inFlight_ || graceOver) {
        if (inFlight_) {
          logf(LogLevel::Warning, "stopping: abandoning cycle %llu", static_cast<unsigned long long>(inFlight_->cycle_id));
          if (inFlight_->origin == CycleOrigin::Plc || inFlight_->origin == CycleOrigin::Continuous) {
            // The PLC's job gets an answer: error 5 (abandoned).
            report_.job_id = inFlight_->job_id;
            report_.recipe_id = inFlight_->recipe_id;
            report_.error_code = static_cast<std::uint16_t>(CycleError::Abandoned);
            report_.pick_valid = 0;
            publish();
          }
        }
        break;
      }
    }
    fds.clear();
    fds.push_back({signalFd_, POLLIN, 0});
    fds.push_back({modbus_->command_fd(), POLLIN, 0});
    fds.push_back({cell_ ? cell_->resultFd() : -1, POLLIN, 0});
    fds.push_back({timerFd_, POLLIN, 0});
    fds.push_back({listenFd_, POLLIN, 0});
    fds.push_back({calib_ ? calib_->completionFd() : -1, POLLIN, 0});
    for (const auto& c : clients_) fds.push_back({c.fd, POLLIN, 0});
    const int n = ::poll(fds.data(), fds.size(), stopping_ ? 100 : -1);
    if (n < 0 && errno != EINTR) {
      logf(LogLevel::Error, "poll: %s", std::strerror(errno));
      break;
    }
    if (fds[0].revents & POLLIN) {
      signalfd_siginfo si{};
      while (::read(signalFd_, &si, sizeof si) == sizeof si) {
        if (si.ssi_signo == SIGHUP) {
          logf(LogLevel::Info, "SIGHUP: reloading the configuration after the current cycle");
          reloadPending_ = true;
          updateReady();
        } else if (!stopping_) {
          logf(LogLevel::Notice, "%s: stopping%s", strsignal(static_cast<int>(si.ssi_signo)),
               inFlight_ ? " after the current cycle" : "");
          stopping_ = true;
          stopRequested_ = Clock::now();
          sd_notify(0, "STOPPING=1");
          updateReady();
        }
      }
    }
    if (fds[2].revents & POLLIN && cell_) {
      while (CycleResult* r = cell_->beginResult()) {
        const CycleResult copy = *r;  // fixed-size copy; hands the slot back at once
        cell_->endResult();
        onResult(copy);
      }
    }
    if (fds[1].revents & POLLIN) {
      while (auto cmd = modbus_->next_command()) {
        if (!stopping_)
          onPlcCommand(*cmd);
        else if (cmd->kind == motion::PlcCommand::Kind::Trigger)
          answerJob(cmd->job_id, cmd->recipe_id, CycleError::Abandoned, "mfcd is stopping");
      }
    }
    if (fds[3].revents & POLLIN) onTimer();
    if (fds[4].revents & POLLIN) acceptControlClient();
    if (fds[5].revents & POLLIN) onCalibrationDone();
    for (std::size_t i = 6; i < fds.size(); ++i) {
      if (!fds[i].revents) continue;
      const int fd = fds[i].fd;
      for (auto& c : clients_)
        if (c.fd == fd) {
          readControlClient(c);
          break;
        }
    }
    afterCycle();
  }

  // Clean stop: no more triggers, cell stopped (LEDs off), robot link closed.
  if (pendingPlc_ && pendingPlc_->kind == motion::PlcCommand::Kind::Trigger)
    answerJob(pendingPlc_->job_id, pendingPlc_->recipe_id, CycleError::Abandoned, "mfcd is stopping");
  pendingPlc_.reset();
  report_.ready = 0;
  publish();
  for (const auto& w : waiters_) reply(w.fd, {{"ok", false}, {"error", "mfcd is stopping"}});
  waiters_.clear();
  calib_.reset();  // joins the worker after the job it is running (an abandoned session writes nothing)
  cell_.reset();
  if (can_) can_->stop();
  // The last report (a final job's result, READY 0) reaches every connected PLC before the
  // connections close: each gets up to one second to poll once more.
  if (!modbus_->drain(std::chrono::seconds(1))) logf(LogLevel::Notice, "stopping: a Modbus client did not poll within 1 s");
  modbus_->stop();
  shutdownFds();
  logf(LogLevel::Notice, "mfcd stopped");
  return 0;
}

}  // namespace

std::optional<DaemonOptions> parseCommandLine(int argc, char** argv, int& exitCode) {
  DaemonOptions o;
  exitCode = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* name) -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(std::string(name) + " needs a value");
      return argv[++i];
    };
    try {
      if (a == "-c" || a == "--config") o.configFile = value("--config");
      else if (a == "--data-dir") o.dataDir = value("--data-dir");
      else if (a == "-f" || a == "--foreground") o.foreground = true;
      else if (a == "--check-config") o.checkConfig = true;
      else if (a == "--benchmark") o.benchmarkCycles = std::stoi(value("--benchmark"));
      else if (a == "--benchmark-json") o.benchmarkJson = value("--benchmark-json");
      else if (a == "-h" || a == "--help") {
        std::fputs(kUsage, stdout);
        return std::nullopt;
      } else {
        throw std::invalid_argument("unknown option " + a);
      }
    } catch (const std::exception& e) {
      std::fprintf(stderr, "mfcd: %s\n%s", e.what(), kUsage);
      exitCode = 2;
      return std::nullopt;
    }
  }
  return o;
}

int runDaemon(const DaemonOptions& options, const VisionStageFactory& vision) {
  Daemon d(options, vision);
  return d.run();
}

int daemonMain(int argc, char** argv, const VisionStageFactory& vision) {
  int code = 0;
  const auto options = parseCommandLine(argc, argv, code);
  if (!options) return code;
  return runDaemon(*options, vision);
}

}  // namespace mfcd::daemon
