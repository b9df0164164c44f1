#include "daemon/daemon.hpp"

#include <poll.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/signalfd.h>
#include <sys/timerfd.h>
#include <systemd/sd-daemon.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>

#include "daemon/daemon_impl.hpp"
#include "daemon/frame_source.hpp"
#include "daemon/log.hpp"
#include "tools/common/build_version.hpp"

namespace mfcd::daemon {

using nlohmann::json;

namespace {

double msSince(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

}  // namespace

DaemonConfig Daemon::load() const {
  return options_.configFile.empty() ? loadEmbeddedConfig(options_.dataDir)
                                     : loadConfigFile(options_.configFile, options_.dataDir);
}

void Daemon::startCell(const DaemonConfig& config) {
  auto cell = std::make_unique<Cell>(config, vision_, source_);
  cell->start();
  cell_ = std::move(cell);
  watchCell();
  showCellOnWeb(config);
  logf(LogLevel::Info, "cell ready: camera %s; vision %s", cell_->sourceDescription().c_str(),
       cell_->visionDescription().c_str());
}

void Daemon::showCellOnWeb(const DaemonConfig& config) {
  if (!webView_ || !cell_) return;
  vision::CameraConfig camera;
  try {
    camera = vision::load_camera_config(config.camera.model);
  } catch (const std::exception&) {
    // The cell started with this file; a file changed since only misplaces the overlay's dots.
  }
  webView_->setCell(cell_->webFrames(), cell_->parts(), camera);
}

void Daemon::dropCell() {
  if (webView_) webView_->setCell(nullptr, {}, {});
  cell_.reset();
  watchCell();
}

void Daemon::watchCell() {
  if (watchedCellFd_ >= 0) loop_.remove(watchedCellFd_);
  watchedCellFd_ = cell_ ? cell_->resultFd() : -1;
  loop_.add(watchedCellFd_, [this] { onCellResults(); });
}

void Daemon::lockMemory() {
  if (!config_.lock_memory) return;
  // With MCL_FUTURE every later mapping must fit under RLIMIT_MEMLOCK, or allocations start to fail;
  // only lock when the limit cannot bite (root/CAP_IPC_LOCK or an unlimited limit).
  rlimit lim{};
  getrlimit(RLIMIT_MEMLOCK, &lim);
  if (geteuid() != 0 && lim.rlim_cur != RLIM_INFINITY) {
    logf(LogLevel::Notice,
         "not locking memory: RLIMIT_MEMLOCK is %llu kB (set LimitMEMLOCK=infinity to allow mlockall)",
         static_cast<unsigned long long>(lim.rlim_cur / 1024));
    return;
  }
  if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0)
    logf(LogLevel::Notice, "mlockall failed (%s); running with pageable memory", std::strerror(errno));
  else
    logf(LogLevel::Info, "memory locked (mlockall)");
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
      next.modbus.frame_timeout != config_.modbus.frame_timeout ||
      next.modbus.idle_timeout != config_.modbus.idle_timeout || next.modbus.allow_list != config_.modbus.allow_list)
    logf(LogLevel::Warning,
         "reload: modbus.* changed; the Modbus server keeps its settings until mfcd restarts "
         "(reloading keeps PLC connections open)");
  if (next.control_socket != config_.control_socket)
    logf(LogLevel::Warning, "reload: daemon.control_socket changed; it takes effect at the next start");
  if (next.web.enabled != config_.web.enabled || next.web.bind_address != config_.web.bind_address ||
      next.web.port != config_.web.port || next.web.allow_list != config_.web.allow_list ||
      next.web_root != config_.web_root)
    logf(LogLevel::Warning, "reload: web.* changed; the web view keeps its settings until mfcd restarts");
  next.modbus = config_.modbus;
  next.control_socket = config_.control_socket;
  next.web = config_.web;
  next.web_root = config_.web_root;
  dropCell();  // stops the threads, LEDs off, releases the devices for the new cell
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
  next.can.software_version = config_.can.software_version;
  next.can.software_patch = config_.can.software_patch;
  link_.reconfigure_can(next.can_enabled, next.can);
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
                stopping_   ? "stopping"
                : inFlight_ ? "busy"
                : cellOk_   ? "ready"
                            : "camera/vision failed",
                toString(config_.mode), static_cast<unsigned long long>(stats_.cycles()),
                static_cast<unsigned long long>(stats_.overruns()), stats_.percentileMs(50));
  if (lastStatus_ != status) {
    lastStatus_ = status;
    sd_notify(0, status);
  }
  if (webView_) {
    json stats = stats_.toJson();
    stats["budget_ms"] = config_.cycle_budget_ms;
    webView_->update(statusJson(), lastResult_, std::move(stats));
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
  [[maybe_unused]] ssize_t n = ::read(timerFd_.get(), &expirations, sizeof expirations);
  const auto now = Clock::now();
  if (cell_) {
    if (cell_->acquisitionHeartbeat() != lastAcqBeat_) lastAcqBeat_ = cell_->acquisitionHeartbeat(), acqMoved_ = now;
    if (cell_->visionHeartbeat() != lastVisionBeat_) lastVisionBeat_ = cell_->visionHeartbeat(), visionMoved_ = now;
  }
  const bool linkUp = link_.serving();
  if (framePathMoving(now, kHeartbeatGrace)) link_.lease_health(now + kHeartbeatLease);
  if (!linkUp && !linkDownLogged_) {
    logf(LogLevel::Error, "the Modbus server thread has ended; withholding the systemd watchdog so mfcd is restarted");
    linkDownLogged_ = true;
  }
  // A thread is stuck when it has not woken for longer than any cycle may take.
  const auto stall = std::max<std::chrono::milliseconds>(std::chrono::seconds(5),
                                                         3 * std::chrono::milliseconds(config_.cycle_budget_ms));
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
    std::printf("| %s | %.1f | %.1f | %.1f | %.1f |\n", stage, stats_.percentileMs(stage, 50),
                stats_.percentileMs(stage, 90), stats_.percentileMs(stage, 99), stats_.percentileMs(stage, 100));
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
    const bool written = std::fprintf(f, "%s\n", j.dump(2, ' ', false, json::error_handler_t::replace).c_str()) > 0;
    if (std::fclose(f) != 0 || !written) {
      logf(LogLevel::Error, "writing %s failed: %s", options_.benchmarkJson.c_str(), std::strerror(errno));
      return 1;
    }
  }
  cell_.reset();
  return 0;
}

void Daemon::onSignal() {
  signalfd_siginfo si{};
  while (::read(signalFd_.get(), &si, sizeof si) == sizeof si) {
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

void Daemon::onCellResults() {
  if (!cell_) return;
  while (CycleResult* r = cell_->beginResult()) {
    const CycleResult copy = *r;  // fixed-size copy; hands the slot back at once
    cell_->endResult();
    onResult(copy);
  }
}

void Daemon::onPlcCommands() {
  while (auto cmd = link_.next_command()) {
    if (!stopping_)
      onPlcCommand(*cmd);
    else if (startsJob(cmd->kind))
      answerJob(cmd->job_id, cmd->recipe_id, CycleError::Abandoned, "mfcd is stopping");
  }
}

// The robot link, the control socket, the calibration service, signals and the tick; false when
// one cannot start (logged).
bool Daemon::startServices() {
  try {
    motion::ModbusServerConfig modbus = config_.modbus;
    // mfcd's release in registers 53..54 (project version "major.minor.patch").
    unsigned major = 0, minor = 0, patch = 0;
    if (std::sscanf(version(), "%u.%u.%u", &major, &minor, &patch) == 3) {
      modbus.software_version = static_cast<std::uint16_t>((std::min(major, 255u) << 8) | std::min(minor, 255u));
      modbus.software_patch = static_cast<std::uint16_t>(std::min(patch, 65535u));
    }
    // The same release in MFCD_Version; kept in config_.can so a reload's new publisher has it too.
    config_.can.software_version = modbus.software_version;
    config_.can.software_patch = modbus.software_patch;
    link_.start(modbus, config_.can_enabled, config_.can);
    control_.open(config_.control_socket);
    calib_ = std::make_unique<CalibrationService>();
  } catch (const std::exception& e) {
    logf(LogLevel::Error, "%s", e.what());
    return false;
  }
  if (config_.web.enabled) {
    try {
      webView_ = std::make_unique<WebView>(config_.snapshots.directory);
      web_ = std::make_unique<WebServer>(config_.web, *webView_, config_.web_root);
      web_->start();
      logf(LogLevel::Info, "web view on http://%s:%u/ (%s)", config_.web.bind_address.c_str(), web_->port(),
           config_.web_root.c_str());
      showCellOnWeb(config_);
    } catch (const std::exception& e) {
      logf(LogLevel::Error, "web view: %s", e.what());
      return false;
    }
  }
  registerCommands();
  sigset_t mask;
  sigemptyset(&mask);
  for (int s : {SIGTERM, SIGINT, SIGHUP}) sigaddset(&mask, s);
  signalFd_.reset(::signalfd(-1, &mask, SFD_CLOEXEC | SFD_NONBLOCK));
  timerFd_.reset(::timerfd_create(CLOCK_MONOTONIC, TFD_CLOEXEC | TFD_NONBLOCK));
  if (!signalFd_ || !timerFd_) {
    logf(LogLevel::Error, "signalfd/timerfd: %s", std::strerror(errno));
    return false;
  }
  if (sd_watchdog_enabled(0, &watchdogUsec_) <= 0) watchdogUsec_ = 0;
  // At most 500 ms: the HEARTBEAT lease (onTimer) and half the systemd watchdog interval.
  const std::uint64_t tickUs = watchdogUsec_ ? std::clamp<std::uint64_t>(watchdogUsec_ / 2, 1000, 500'000) : 500'000;
  itimerspec its{};
  its.it_interval.tv_sec = static_cast<time_t>(tickUs / 1'000'000);
  its.it_interval.tv_nsec = static_cast<long>((tickUs % 1'000'000) * 1000);
  its.it_value = its.it_interval;
  ::timerfd_settime(timerFd_.get(), 0, &its, nullptr);
  // Registration order is dispatch order: results before commands, so a finished cycle frees
  // the cell before the next trigger is looked at.
  loop_.add(signalFd_.get(), [this] { onSignal(); });
  watchCell();
  loop_.add(link_.command_fd(), [this] { onPlcCommands(); });
  loop_.add(timerFd_.get(), [this] { onTimer(); });
  loop_.add(calib_->completionFd(), [this] { onCalibrationDone(); });
  return true;
}

void Daemon::mainLoop() {
  for (;;) {
    if (stopping_) {
      // Finish the cycle in flight (bounded by its deadline); abandon it if it outlives the grace:
      // its budget, at most kStopGraceMs, + 2 s. With the 1 s drain and the joins this stays
      // inside the unit's TimeoutStopSec=20 for any budget.
      constexpr int kStopGraceMs = 10000;
      const bool graceOver = msSince(stopRequested_) > std::min(config_.cycle_budget_ms, kStopGraceMs) + 2000;
      if (!inFlight_ || graceOver) {
        if (inFlight_) {
          logf(LogLevel::Warning, "stopping: abandoning cycle %llu",
               static_cast<unsigned long long>(inFlight_->cycle_id));
          if (inFlight_->origin == CycleOrigin::Plc || inFlight_->origin == CycleOrigin::Continuous)
            answerJob(inFlight_->job_id, inFlight_->recipe_id, CycleError::Abandoned,
                      "mfcd stopped before the cycle finished");
        }
        return;
      }
    }
    // The barrier: nothing one event's handling throws ends the daemon.
    try {
      if (!loop_.run_once(stopping_ ? 100 : -1)) {
        logf(LogLevel::Error, "poll: %s", std::strerror(errno));
        return;
      }
      afterCycle();
    } catch (const std::exception& e) {
      logf(LogLevel::Error, "main loop: %s; continuing", e.what());
    }
  }
}

// Clean stop: no more triggers, every waiting job answered, cell stopped (LEDs off), robot link
// drained and closed.
void Daemon::shutdown() {
  if (pendingPlc_ && startsJob(pendingPlc_->kind))
    answerJob(pendingPlc_->job_id, pendingPlc_->recipe_id, CycleError::Abandoned, "mfcd is stopping");
  pendingPlc_.reset();
  report_.ready = 0;
  publish();
  for (const auto& w : waiters_) control_.reply(w.client, {{"ok", false}, {"error", "mfcd is stopping"}});
  waiters_.clear();
  calib_.reset();  // joins the worker after the job it is running (an abandoned session writes nothing)
  if (web_) web_->stop();
  dropCell();
  link_.stop(std::chrono::seconds(1));
  control_.close();
  logf(LogLevel::Notice, "mfcd stopped");
}

int Daemon::run() {
  logOpen("mfcd", options_.foreground || options_.benchmarkCycles > 0, LogLevel::Info);
  logf(LogLevel::Notice, "mfcd %s (%s) starting", version(), git_commit());
  try {
    config_ = load();
  } catch (const std::exception& e) {
    logf(LogLevel::Error, "configuration: %s", e.what());
    // --check-config is run by a person: the reason goes to the terminal, not only to the journal.
    if (options_.checkConfig && !options_.foreground) std::fprintf(stderr, "mfcd: configuration: %s\n", e.what());
    return 2;
  }
  logSetLevel(config_.log_level);
  if (options_.checkConfig) {
    std::printf("%s: valid\n", config_.source.c_str());
    return 0;
  }
  if (options_.ledsOff) {
    try {
      const std::string done = switchLedsOff(config_);
      logf(LogLevel::Notice, "%s", done.c_str());
      std::printf("%s\n", done.c_str());
      return 0;
    } catch (const std::exception& e) {
      logf(LogLevel::Error, "switching the LEDs off: %s", e.what());
      return 1;
    }
  }
  selectedRecipe_ = config_.default_recipe;

  // Signals are taken through a signalfd: block them before any thread starts so all inherit it.
  sigset_t mask;
  sigemptyset(&mask);
  for (int s : {SIGTERM, SIGINT, SIGHUP}) sigaddset(&mask, s);
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
  if (!startServices()) {
    dropCell();
    return 1;
  }
  report_.vision_ok = 1;
  link_.lease_health(Clock::now() + std::chrono::seconds(1));
  updateReady();
  publish();
  sd_notify(0, "READY=1");
  notifyStatus();
  logf(LogLevel::Notice, "mfcd ready (%s, %s mode, budget %d ms)", config_.source.c_str(), toString(config_.mode),
       config_.cycle_budget_ms);
  afterCycle();  // continuous mode starts its first cycle
  mainLoop();
  shutdown();
  return 0;
}

int runDaemon(const DaemonOptions& options, const VisionStageFactory& vision, const FrameSourceFactory& source) {
  Daemon d(options, vision, source);
  return d.run();
}

int daemonMain(int argc, char** argv, const VisionStageFactory& vision, const FrameSourceFactory& source) {
  int code = 0;
  const auto options = parseCommandLine(argc, argv, code);
  if (!options) return code;
  return runDaemon(*options, vision, source);
}

}  // namespace mfcd::daemon
