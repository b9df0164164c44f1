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

double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

}  // namespace

DaemonConfig Daemon::load() const {
  return options_.config_file.empty() ? load_embedded_config(options_.data_dir)
                                      : load_config_file(options_.config_file, options_.data_dir);
}

void Daemon::start_cell(const DaemonConfig& config) {
  auto cell = std::make_unique<Cell>(config, vision_, source_);
  cell->start();
  cell_ = std::move(cell);
  watch_cell();
  show_cell_on_web(config);
  logf(LogLevel::Info, "cell ready: camera %s; vision %s", cell_->source_description().c_str(),
       cell_->vision_description().c_str());
}

void Daemon::show_cell_on_web(const DaemonConfig& config) {
  if (!web_view_ || !cell_) return;
  vision::CameraConfig camera;
  try {
    camera = vision::load_camera_config(config.camera.model);
  } catch (const std::exception&) {
    // The cell started with this file; a file changed since only misplaces the overlay's dots.
  }
  web_view_->set_cell(cell_->web_frames(), cell_->parts(), camera);
}

void Daemon::drop_cell() {
  if (web_view_) web_view_->set_cell(nullptr, {}, {});
  cell_.reset();
  watch_cell();
}

void Daemon::watch_cell() {
  if (watched_cell_fd_ >= 0) loop_.remove(watched_cell_fd_);
  watched_cell_fd_ = cell_ ? cell_->result_fd() : -1;
  loop_.add(watched_cell_fd_, [this] { on_cell_results(); });
}

void Daemon::lock_memory() {
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
  drop_cell();  // stops the threads, LEDs off, releases the devices for the new cell
  try {
    start_cell(next);
    cell_ok_ = true;
  } catch (const std::exception& e) {
    message = std::string("reload failed, restored the running configuration: ") + e.what();
    logf(LogLevel::Error, "%s", message.c_str());
    try {
      start_cell(config_);
      cell_ok_ = true;
    } catch (const std::exception& e2) {
      cell_ok_ = false;
      logf(LogLevel::Error, "restoring the previous cell failed too: %s", e2.what());
    }
    sd_notify(0, "READY=1");
    return false;
  }
  next.can.software_version = config_.can.software_version;
  next.can.software_patch = config_.can.software_patch;
  link_.reconfigure_can(next.can_enabled, next.can);
  config_ = std::move(next);
  log_set_level(config_.log_level);
  if (!config_.recipe(selected_recipe_)) selected_recipe_ = config_.default_recipe;
  message = "reloaded " + config_.source;
  logf(LogLevel::Info, "%s", message.c_str());
  sd_notify(0, "READY=1");
  return true;
}

void Daemon::notify_status() {
  char status[256];
  std::snprintf(status, sizeof status, "STATUS=%s, %s mode, %llu cycles, %llu overruns, p50 %.0f ms",
                stopping_    ? "stopping"
                : in_flight_ ? "busy"
                : cell_ok_   ? "ready"
                             : "camera/vision failed",
                to_string(config_.mode), static_cast<unsigned long long>(stats_.cycles()),
                static_cast<unsigned long long>(stats_.overruns()), stats_.percentile_ms(50));
  if (last_status_ != status) {
    last_status_ = status;
    sd_notify(0, status);
  }
  if (web_view_) {
    json stats = stats_.to_json();
    stats["budget_ms"] = config_.cycle_budget_ms;
    web_view_->update(status_json(), last_result_, std::move(stats));
  }
}

bool Daemon::frame_path_moving(Clock::time_point now, std::chrono::milliseconds grace) const {
  if (!cell_) return true;
  const bool busy = now < busy_until_ + grace;
  return (busy || now - acq_moved_ < grace) && (busy || now - vision_moved_ < grace);
}

// Every tick (at most 500 ms apart): liveness for the PLC and for systemd. HEARTBEAT gets a
// lease of one second while the frame path moves within kHeartbeatGrace (an idle thread wakes
// every 200 ms), so a hang of the main thread (no tick), of a frame-path thread or of a cycle
// past its deadline freezes HEARTBEAT within ~2.5 s. The systemd watchdog, which restarts mfcd,
// waits longer (stall) and is also withheld once the robot link's thread has died.
void Daemon::on_timer() {
  constexpr std::chrono::milliseconds kHeartbeatGrace{1000}, kHeartbeatLease{1000};
  std::uint64_t expirations;
  [[maybe_unused]] ssize_t n = ::read(timer_fd_.get(), &expirations, sizeof expirations);
  const auto now = Clock::now();
  if (cell_) {
    if (cell_->acquisition_heartbeat() != last_acq_beat_)
      last_acq_beat_ = cell_->acquisition_heartbeat(), acq_moved_ = now;
    if (cell_->vision_heartbeat() != last_vision_beat_)
      last_vision_beat_ = cell_->vision_heartbeat(), vision_moved_ = now;
  }
  const bool link_up = link_.serving();
  if (frame_path_moving(now, kHeartbeatGrace)) link_.lease_health(now + kHeartbeatLease);
  if (!link_up && !link_down_logged_) {
    logf(LogLevel::Error, "the Modbus server thread has ended; withholding the systemd watchdog so mfcd is restarted");
    link_down_logged_ = true;
  }
  // A thread is stuck when it has not woken for longer than any cycle may take.
  const auto stall = std::max<std::chrono::milliseconds>(std::chrono::seconds(5),
                                                         3 * std::chrono::milliseconds(config_.cycle_budget_ms));
  const bool moving = frame_path_moving(now, stall);
  if (watchdog_usec_ && moving && link_up) sd_notify(0, "WATCHDOG=1");
  if (!moving && !stuck_logged_) {
    logf(LogLevel::Error, "a frame-path thread has not moved for %lld ms; withholding the systemd watchdog",
         static_cast<long long>(stall.count()));
    stuck_logged_ = true;
  }
  if (moving) stuck_logged_ = false;
  notify_status();
}

int Daemon::run_benchmark() {
  const int n = options_.benchmark_cycles;
  for (int i = 0; i < n; ++i) {
    start_cycle(CycleOrigin::Benchmark, 0, static_cast<std::uint16_t>(config_.default_recipe), 0, false);
    for (;;) {
      pollfd p{cell_->result_fd(), POLLIN, 0};
      ::poll(&p, 1, 1000);
      bool done = false;
      while (CycleResult* r = cell_->begin_result()) {
        const CycleResult copy = *r;
        cell_->end_result();
        if (copy.kind == CycleResult::Kind::Cycle) {
          on_result(copy);
          done = true;
        }
      }
      if (done) break;
    }
  }
  json j = stats_.to_json();
  j["budget_ms"] = config_.cycle_budget_ms;
  j["camera"] = cell_->source_description();
  j["vision"] = cell_->vision_description();
  std::printf("%s\n", j.dump(2, ' ', false, json::error_handler_t::replace).c_str());
  std::printf("\n| stage | p50 ms | p90 ms | p99 ms | max ms |\n|---|---|---|---|---|\n");
  for (const char* stage : {"total", "capture", "vision"})
    std::printf("| %s | %.1f | %.1f | %.1f | %.1f |\n", stage, stats_.percentile_ms(stage, 50),
                stats_.percentile_ms(stage, 90), stats_.percentile_ms(stage, 99), stats_.percentile_ms(stage, 100));
  std::printf("\n%llu cycles, %llu overruns of %d ms, %llu degraded, %llu errors, %llu picks\n",
              static_cast<unsigned long long>(stats_.cycles()), static_cast<unsigned long long>(stats_.overruns()),
              config_.cycle_budget_ms, static_cast<unsigned long long>(stats_.degraded()),
              static_cast<unsigned long long>(stats_.errors()), static_cast<unsigned long long>(stats_.picks()));
  if (!options_.benchmark_json.empty()) {
    FILE* f = std::fopen(options_.benchmark_json.c_str(), "w");
    if (!f) {
      logf(LogLevel::Error, "cannot write %s: %s", options_.benchmark_json.c_str(), std::strerror(errno));
      return 1;
    }
    const bool written = std::fprintf(f, "%s\n", j.dump(2, ' ', false, json::error_handler_t::replace).c_str()) > 0;
    if (std::fclose(f) != 0 || !written) {
      logf(LogLevel::Error, "writing %s failed: %s", options_.benchmark_json.c_str(), std::strerror(errno));
      return 1;
    }
  }
  cell_.reset();
  return 0;
}

void Daemon::on_signal() {
  signalfd_siginfo si{};
  while (::read(signal_fd_.get(), &si, sizeof si) == sizeof si) {
    if (si.ssi_signo == SIGHUP) {
      logf(LogLevel::Info, "SIGHUP: reloading the configuration after the current cycle");
      reload_pending_ = true;
      update_ready();
    } else if (!stopping_) {
      logf(LogLevel::Notice, "%s: stopping%s", strsignal(static_cast<int>(si.ssi_signo)),
           in_flight_ ? " after the current cycle" : "");
      stopping_ = true;
      stop_requested_ = Clock::now();
      sd_notify(0, "STOPPING=1");
      update_ready();
    }
  }
}

void Daemon::on_cell_results() {
  if (!cell_) return;
  while (CycleResult* r = cell_->begin_result()) {
    const CycleResult copy = *r;  // fixed-size copy; hands the slot back at once
    cell_->end_result();
    on_result(copy);
  }
}

void Daemon::on_plc_commands() {
  while (auto cmd = link_.next_command()) {
    if (!stopping_)
      on_plc_command(*cmd);
    else if (starts_job(cmd->kind))
      answer_job(cmd->job_id, cmd->recipe_id, CycleError::Abandoned, "mfcd is stopping");
  }
}

// The robot link, the control socket, the calibration service, signals and the tick; false when
// one cannot start (logged).
bool Daemon::start_services() {
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
      web_view_ = std::make_unique<WebView>(config_.snapshots.directory);
      web_ = std::make_unique<WebServer>(config_.web, *web_view_, config_.web_root);
      web_->start();
      logf(LogLevel::Info, "web view on http://%s:%u/ (%s)", config_.web.bind_address.c_str(), web_->port(),
           config_.web_root.c_str());
      show_cell_on_web(config_);
    } catch (const std::exception& e) {
      logf(LogLevel::Error, "web view: %s", e.what());
      return false;
    }
  }
  register_commands();
  sigset_t mask;
  sigemptyset(&mask);
  for (int s : {SIGTERM, SIGINT, SIGHUP}) sigaddset(&mask, s);
  signal_fd_.reset(::signalfd(-1, &mask, SFD_CLOEXEC | SFD_NONBLOCK));
  timer_fd_.reset(::timerfd_create(CLOCK_MONOTONIC, TFD_CLOEXEC | TFD_NONBLOCK));
  if (!signal_fd_ || !timer_fd_) {
    logf(LogLevel::Error, "signalfd/timerfd: %s", std::strerror(errno));
    return false;
  }
  if (sd_watchdog_enabled(0, &watchdog_usec_) <= 0) watchdog_usec_ = 0;
  // At most 500 ms: the HEARTBEAT lease (on_timer) and half the systemd watchdog interval.
  const std::uint64_t tick_us = watchdog_usec_ ? std::clamp<std::uint64_t>(watchdog_usec_ / 2, 1000, 500'000) : 500'000;
  itimerspec its{};
  its.it_interval.tv_sec = static_cast<time_t>(tick_us / 1'000'000);
  its.it_interval.tv_nsec = static_cast<long>((tick_us % 1'000'000) * 1000);
  its.it_value = its.it_interval;
  ::timerfd_settime(timer_fd_.get(), 0, &its, nullptr);
  // Registration order is dispatch order: results before commands, so a finished cycle frees
  // the cell before the next trigger is looked at.
  loop_.add(signal_fd_.get(), [this] { on_signal(); });
  watch_cell();
  loop_.add(link_.command_fd(), [this] { on_plc_commands(); });
  loop_.add(timer_fd_.get(), [this] { on_timer(); });
  loop_.add(calib_->completion_fd(), [this] { on_calibration_done(); });
  return true;
}

void Daemon::main_loop() {
  for (;;) {
    if (stopping_) {
      // Finish the cycle in flight (bounded by its deadline); abandon it if it outlives the grace:
      // its budget, at most kStopGraceMs, + 2 s. With the 1 s drain and the joins this stays
      // inside the unit's TimeoutStopSec=20 for any budget.
      constexpr int kStopGraceMs = 10000;
      const bool grace_over = ms_since(stop_requested_) > std::min(config_.cycle_budget_ms, kStopGraceMs) + 2000;
      if (!in_flight_ || grace_over) {
        if (in_flight_) {
          logf(LogLevel::Warning, "stopping: abandoning cycle %llu",
               static_cast<unsigned long long>(in_flight_->cycle_id));
          if (in_flight_->origin == CycleOrigin::Plc || in_flight_->origin == CycleOrigin::Continuous)
            answer_job(in_flight_->job_id, in_flight_->recipe_id, CycleError::Abandoned,
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
      after_cycle();
    } catch (const std::exception& e) {
      logf(LogLevel::Error, "main loop: %s; continuing", e.what());
    }
  }
}

// Clean stop: no more triggers, every waiting job answered, cell stopped (LEDs off), robot link
// drained and closed.
void Daemon::shutdown() {
  if (pending_plc_ && starts_job(pending_plc_->kind))
    answer_job(pending_plc_->job_id, pending_plc_->recipe_id, CycleError::Abandoned, "mfcd is stopping");
  pending_plc_.reset();
  report_.ready = 0;
  publish();
  for (const auto& w : waiters_) control_.reply(w.client, {{"ok", false}, {"error", "mfcd is stopping"}});
  waiters_.clear();
  calib_.reset();  // joins the worker after the job it is running (an abandoned session writes nothing)
  if (web_) web_->stop();
  drop_cell();
  link_.stop(std::chrono::seconds(1));
  control_.close();
  logf(LogLevel::Notice, "mfcd stopped");
}

int Daemon::run() {
  log_open("mfcd", options_.foreground || options_.benchmark_cycles > 0, LogLevel::Info);
  logf(LogLevel::Notice, "mfcd %s (%s) starting", version(), git_commit());
  try {
    config_ = load();
  } catch (const std::exception& e) {
    logf(LogLevel::Error, "configuration: %s", e.what());
    // --check-config is run by a person: the reason goes to the terminal, not only to the journal.
    if (options_.check_config && !options_.foreground) std::fprintf(stderr, "mfcd: configuration: %s\n", e.what());
    return 2;
  }
  log_set_level(config_.log_level);
  if (options_.check_config) {
    std::printf("%s: valid\n", config_.source.c_str());
    return 0;
  }
  if (options_.leds_off) {
    try {
      const std::string done = switch_leds_off(config_);
      logf(LogLevel::Notice, "%s", done.c_str());
      std::printf("%s\n", done.c_str());
      return 0;
    } catch (const std::exception& e) {
      logf(LogLevel::Error, "switching the LEDs off: %s", e.what());
      return 1;
    }
  }
  selected_recipe_ = config_.default_recipe;

  // Signals are taken through a signalfd: block them before any thread starts so all inherit it.
  sigset_t mask;
  sigemptyset(&mask);
  for (int s : {SIGTERM, SIGINT, SIGHUP}) sigaddset(&mask, s);
  pthread_sigmask(SIG_BLOCK, &mask, nullptr);
  ::signal(SIGPIPE, SIG_IGN);

  try {
    start_cell(config_);
    cell_ok_ = true;
  } catch (const std::exception& e) {
    logf(LogLevel::Error, "starting the cell: %s", e.what());
    return 1;
  }
  lock_memory();
  if (options_.benchmark_cycles > 0) return run_benchmark();
  if (!start_services()) {
    drop_cell();
    return 1;
  }
  report_.vision_ok = 1;
  link_.lease_health(Clock::now() + std::chrono::seconds(1));
  update_ready();
  publish();
  sd_notify(0, "READY=1");
  notify_status();
  logf(LogLevel::Notice, "mfcd ready (%s, %s mode, budget %d ms)", config_.source.c_str(), to_string(config_.mode),
       config_.cycle_budget_ms);
  after_cycle();  // continuous mode starts its first cycle
  main_loop();
  shutdown();
  return 0;
}

int run_daemon(const DaemonOptions& options, const VisionStageFactory& vision, const FrameSourceFactory& source) {
  Daemon d(options, vision, source);
  return d.run();
}

int daemon_main(int argc, char** argv, const VisionStageFactory& vision, const FrameSourceFactory& source) {
  int code = 0;
  const auto options = parse_command_line(argc, argv, code);
  if (!options) return code;
  return run_daemon(*options, vision, source);
}

}  // namespace mfcd::daemon
