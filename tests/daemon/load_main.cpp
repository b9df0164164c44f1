// mfcd_load: load, churn and soak of the real daemon on the simulated cell, with figures.
//
//   mfcd_load --daemon PATH [--seconds S] [--jobs J] [--clients N] [--poll-ms P] [--churn K]
//             [--budget-ms B] [--warmup-s W] [--max-rss-growth-kb KB] [--sighup-ms H]
//             [--max-heartbeat-stand-s T] [--camera rendered|pattern] [--vision-ms V] [--json FILE]
//
// While one PLC triggers jobs back to back, N more Modbus clients (libmodbus) read the status block
// every P ms, a control client asks for status twice a second, and (with --churn) K connections
// are opened and closed, half of them dropped mid-frame; with --sighup-ms the daemon is sent SIGHUP
// (reload: the cell is rebuilt) every H ms, at whatever phase its cycle is in. Every job must end with its JOB_ID_ECHO
// and no error code; no poller may see a failed read or HEARTBEAT going backwards or standing
// still for 3 s; the daemon's open descriptors must not grow and its RSS not grow by more than
// KB after the warm-up. Prints a JSON object and a table; exits 0 when every check holds, 1 when
// one fails, 77 when the simulated cell cannot run here (no offscreen OpenGL).
//
// The run ends after S seconds or, with --jobs, once J jobs have been answered (S is then the upper
// bound). What bounds the cycle rate is the simulated camera: `--camera rendered` (default) renders
// the bin of CAD parts with llvmpipe for every frame set (8 flashes + ambient, 640x480: ~150-200 ms
// of a 2-core machine's time); `--camera pattern` is the same daemon on a cell without meshes, whose
// simulated camera serves the HAL test pattern through the same sequencer and frame path (~5 ms per
// frame set), with the test backend checking every frame's tag (LED mask, freshness) and reporting
// one stand-in pick per cycle (tests/daemon/test_vision_stage.hpp): every job must then carry a
// pick. --vision-ms sets the test backend's work time per cycle (default 20).
#include <arpa/inet.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <mutex>
#include <stdexcept>
#include <thread>

#include "base/unique_fd.hpp"
#include "daemon_process.hpp"
#include "motion/register_map.hpp"

using namespace mfcd::daemon::test;
namespace reg = mfcd::motion::reg;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

namespace {

struct Options {
  std::string daemon;
  double seconds = 20;
  long jobs = 0;  // > 0: end once this many jobs have been answered
  int clients = 32;
  int poll_ms = 10;
  int churn = 0;
  int budget_ms = 1000;
  double warmup_s = 5;
  long max_rss_growth_kb = 1024;
  int sighup_ms = 0;
  double max_heartbeat_stand_s = 3.0;
  std::string camera = "rendered";  // rendered | pattern
  int vision_ms = 20;               // the test backend's work time per cycle
  std::string json_file;
};

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
      return argv[++i];
    };
    if (a == "--daemon")
      o.daemon = value();
    else if (a == "--seconds")
      o.seconds = std::stod(value());
    else if (a == "--clients")
      o.clients = std::stoi(value());
    else if (a == "--poll-ms")
      o.poll_ms = std::stoi(value());
    else if (a == "--churn")
      o.churn = std::stoi(value());
    else if (a == "--budget-ms")
      o.budget_ms = std::stoi(value());
    else if (a == "--warmup-s")
      o.warmup_s = std::stod(value());
    else if (a == "--max-rss-growth-kb")
      o.max_rss_growth_kb = std::stol(value());
    else if (a == "--json")
      o.json_file = value();
    else if (a == "--sighup-ms")
      o.sighup_ms = std::stoi(value());
    else if (a == "--max-heartbeat-stand-s")
      o.max_heartbeat_stand_s = std::stod(value());
    else if (a == "--jobs")
      o.jobs = std::stol(value());
    else if (a == "--camera")
      o.camera = value();
    else if (a == "--vision-ms")
      o.vision_ms = std::stoi(value());
    else
      throw std::invalid_argument("unknown option " + a);
  }
  if (o.daemon.empty()) throw std::invalid_argument("--daemon PATH is required");
  if (o.clients < 0 || o.clients > 60) throw std::invalid_argument("--clients must be 0..60");
  if (o.camera != "rendered" && o.camera != "pattern") throw std::invalid_argument("--camera is rendered or pattern");
  if (o.vision_ms < 0 || o.vision_ms > 10000) throw std::invalid_argument("--vision-ms must be 0..10000");
  if (o.jobs < 0) throw std::invalid_argument("--jobs must be >= 0");
  return o;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(p / 100.0 * static_cast<double>(v.size())))];
}

long rss_kb(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string key;
  while (in >> key)
    if (key == "VmRSS:") {
      long kb = 0;
      in >> kb;
      return kb;
    }
  return -1;
}

int fd_count(pid_t pid) {
  int n = 0;
  std::error_code ec;
  for (auto it = fs::directory_iterator("/proc/" + std::to_string(pid) + "/fd", ec);
       !ec && it != fs::directory_iterator(); ++it)
    ++n;
  return n;
}

modbus_t* connect_client(int port) {
  modbus_t* ctx = modbus_new_tcp("127.0.0.1", port);
  if (!ctx) return nullptr;
  modbus_set_response_timeout(ctx, 2, 0);
  if (modbus_connect(ctx) != 0) {
    modbus_free(ctx);
    return nullptr;
  }
  return ctx;
}

struct PollerResult {
  std::vector<double> latency_ms;
  long reads = 0, failures = 0, heartbeat_backwards = 0;
  double longest_heartbeat_stand_s = 0;
};

// One PLC-style poller: reads the status block every poll_ms until `stop`.
void poll_loop(int port, int poll_ms, const std::atomic<bool>& stop, PollerResult& out) {
  modbus_t* ctx = connect_client(port);
  if (!ctx) {
    ++out.failures;
    return;
  }
  out.latency_ms.reserve(200000);
  std::uint16_t regs[28];
  bool have_beat = false;
  std::uint16_t last_beat = 0;
  Clock::time_point beat_changed = Clock::now();
  auto next = Clock::now();
  while (!stop.load()) {
    const auto t0 = Clock::now();
    const int n = modbus_read_registers(ctx, reg::kStatus, 28, regs);
    const auto t1 = Clock::now();
    ++out.reads;
    if (n != 28) {
      ++out.failures;
      modbus_close(ctx);
      modbus_connect(ctx);
    } else {
      out.latency_ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
      const std::uint16_t beat = regs[reg::kHeartbeat - reg::kStatus];
      if (have_beat && beat != last_beat) {
        // Wraps 65535 -> 0; anything else that goes down is a fault.
        if (static_cast<std::uint16_t>(beat - last_beat) > 1000) ++out.heartbeat_backwards;
        out.longest_heartbeat_stand_s =
            std::max(out.longest_heartbeat_stand_s, std::chrono::duration<double>(t1 - beat_changed).count());
        beat_changed = t1;
      }
      if (!have_beat) beat_changed = t1;
      have_beat = true;
      last_beat = beat;
    }
    next += std::chrono::milliseconds(poll_ms);
    std::this_thread::sleep_until(next);
  }
  out.longest_heartbeat_stand_s =
      std::max(out.longest_heartbeat_stand_s, std::chrono::duration<double>(Clock::now() - beat_changed).count());
  modbus_close(ctx);
  modbus_free(ctx);
}

struct PlcResult {
  long jobs = 0, job_errors = 0, lost_jobs = 0, refused = 0, picks = 0;
  std::atomic<long> answered{0};  // jobs whose JOB_ID_ECHO came back (read by the sampling loop)
  std::vector<double> cycle_ms;
};

// The PLC: TRIGGER, wait for the job id echo, read the result; back to back until `stop`.
void plc_loop(int port, const std::atomic<bool>& stop, PlcResult& out) {
  modbus_t* ctx = connect_client(port);
  if (!ctx) {
    ++out.lost_jobs;
    return;
  }
  std::uint16_t job = 1;
  std::uint16_t regs[28];
  while (!stop.load()) {
    if (modbus_read_registers(ctx, reg::kStatus, 28, regs) != 28) {
      std::this_thread::sleep_for(5ms);
      continue;
    }
    if (!(regs[0] & reg::kReady)) {
      std::this_thread::sleep_for(2ms);
      continue;
    }
    const std::uint16_t cmd[4] = {1, job, 0, 0};
    if (modbus_write_registers(ctx, reg::kCommand, 4, cmd) != 4) {
      ++out.refused;
      std::this_thread::sleep_for(5ms);
      continue;
    }
    ++out.jobs;
    const auto end = Clock::now() + 10s;
    bool done = false;
    while (Clock::now() < end) {
      if (modbus_read_registers(ctx, reg::kStatus, 28, regs) == 28 && regs[reg::kJobIdEcho - reg::kStatus] == job) {
        done = true;
        break;
      }
      std::this_thread::sleep_for(2ms);
    }
    if (!done) {
      ++out.lost_jobs;
    } else if (regs[reg::kErrorCode - reg::kStatus] != 0) {
      ++out.job_errors;
      modbus_write_register(ctx, reg::kCommand, 2);  // RESET
    } else {
      out.cycle_ms.push_back(regs[reg::kCycleTimeMs - reg::kStatus]);
      if (regs[0] & reg::kPickValid) ++out.picks;
    }
    if (done) ++out.answered;
    job = static_cast<std::uint16_t>(job == 65535 ? 1 : job + 1);
  }
  modbus_close(ctx);
  modbus_free(ctx);
}

// Connections opened and closed: complete requests, and frames cut off mid-way.
long churn_loop(int port, int cycles, const std::atomic<bool>& stop) {
  long failures = 0;
  for (int i = 0; i < cycles && !stop.load(); ++i) {
    if (i % 2 == 0) {
      modbus_t* ctx = connect_client(port);
      std::uint16_t r;
      if (!ctx || modbus_read_registers(ctx, reg::kMapVersionReg, 1, &r) != 1) ++failures;
      if (ctx) {
        modbus_close(ctx);
        modbus_free(ctx);
      }
    } else {
      mfcd::UniqueFd fd(::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0));
      sockaddr_in dst{};
      dst.sin_family = AF_INET;
      dst.sin_port = htons(static_cast<std::uint16_t>(port));
      inet_pton(AF_INET, "127.0.0.1", &dst.sin_addr);
      if (::connect(fd.get(), reinterpret_cast<sockaddr*>(&dst), sizeof dst) == 0) {
        const std::uint8_t half[5] = {0, 1, 0, 0, 0};  // an MBAP header cut off: the client "dies"
        ::send(fd.get(), half, sizeof half, MSG_NOSIGNAL);
      } else {
        ++failures;
      }
    }
  }
  return failures;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  try {
    o = parse(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mfcd_load: %s\n", e.what());
    return 2;
  }
  DaemonProcess proc("load");
  std::string config = sim_cell_config(proc.dir(), o.budget_ms);
  const std::string port_line = "  port: 0\n";
  config.replace(config.find(port_line), port_line.size(), port_line + "  max_clients: 64\n");
  std::vector<std::string> env{"MFCD_TEST_VISION_MS=" + std::to_string(o.vision_ms)};
  if (o.camera == "pattern") {
    // No recipe names a mesh: the simulated camera serves the HAL test pattern (frame_source.cpp).
    for (std::size_t at; (at = config.find(", mesh: parts/")) != std::string::npos;)
      config.erase(at, config.find('}', at) - at);
    env.push_back("MFCD_TEST_VISION_PATTERN=1");
  }
  proc.write_config(config);
  proc.start(o.daemon, {}, env);
  if (!proc.wait_ready()) {
    const std::string log = proc.log();
    std::fprintf(stderr, "mfcd did not become ready:\n%s\n", log.c_str());
    return log.find("EGL") != std::string::npos || log.find("OpenGL") != std::string::npos ? 77 : 1;
  }
  const int port = proc.modbus_port();
  const pid_t pid = proc.pid();
  const int fds_before = fd_count(pid);

  std::atomic<bool> stop{false};
  std::vector<PollerResult> pollers(static_cast<std::size_t>(o.clients));
  std::vector<std::thread> threads;
  for (auto& p : pollers) threads.emplace_back(poll_loop, port, o.poll_ms, std::cref(stop), std::ref(p));
  PlcResult plc;
  threads.emplace_back(plc_loop, port, std::cref(stop), std::ref(plc));
  std::atomic<long> churn_failures{0}, control_failures{0}, control_requests{0};
  threads.emplace_back([&] { churn_failures = churn_loop(port, o.churn, stop); });
  threads.emplace_back([&] {
    while (!stop.load()) {
      ++control_requests;
      const std::string r = ctl_line(proc.socket(), "{\"cmd\":\"status\"}\n", 5000);
      if (r.empty() || json::parse(r).value("ok", false) != true) ++control_failures;
      std::this_thread::sleep_for(500ms);
    }
  });

  std::atomic<long> reloads{0};
  if (o.sighup_ms > 0)
    threads.emplace_back([&] {
      while (!stop.load()) {
        std::this_thread::sleep_for(std::chrono::milliseconds(o.sighup_ms));
        if (stop.load()) break;
        proc.signal(SIGHUP);
        ++reloads;
      }
    });

  // Samples of the daemon's RSS and descriptors, once a second.
  const auto start = Clock::now();
  long rss_first = -1, rss_warm = -1, rss_last = -1;
  std::vector<double> rss_after_warmup;  // kB, once a second
  json rss_series = json::array();       // [seconds, kB] every 10 s, for the record
  int fds_warm = -1, fds_max = 0, fds_last = 0;
  while (std::chrono::duration<double>(Clock::now() - start).count() < o.seconds && !proc.exited() &&
         (o.jobs == 0 || plc.answered.load() < o.jobs)) {
    std::this_thread::sleep_for(1s);
    const double t = std::chrono::duration<double>(Clock::now() - start).count();
    rss_last = rss_kb(pid);
    fds_last = fd_count(pid);
    if (rss_first < 0) rss_first = rss_last;
    if (rss_series.size() < static_cast<std::size_t>(t / 10.0)) rss_series.push_back({std::round(t), rss_last});
    if (t >= o.warmup_s) {
      if (rss_warm < 0) rss_warm = rss_last, fds_warm = fds_last;
      rss_after_warmup.push_back(static_cast<double>(rss_last));
      fds_max = std::max(fds_max, fds_last);
    }
  }
  const double elapsed_s = std::chrono::duration<double>(Clock::now() - start).count();
  stop = true;
  for (auto& t : threads) t.join();
  // After every client has gone: the descriptor count the daemon returns to.
  std::this_thread::sleep_for(500ms);
  const bool alive = !proc.exited();
  const int fds_idle = alive ? fd_count(pid) : -1;
  proc.signal(SIGTERM);
  const auto code = proc.wait(30000);
  // The daemon's own log lines (stderr, "mfcd[level]: ..."): errors are unexpected in every run.
  long log_errors = 0, log_warnings = 0;
  {
    std::istringstream log(proc.log());
    for (std::string line; std::getline(log, line);) {
      if (line.rfind("mfcd[error]", 0) == 0) ++log_errors;
      if (line.rfind("mfcd[warning]", 0) == 0) ++log_warnings;
    }
  }

  // The heap and the renderer's buffers swing by a few MB from second to second (a bin refilled and
  // rendered anew, freed again): growth is the floor of the last quarter of the samples minus the
  // floor of the first quarter. Transient buffers sit above the floor; a leak lifts it.
  const std::size_t quarter = std::max<std::size_t>(1, rss_after_warmup.size() / 4);
  const double rss_growth_kb =
      rss_after_warmup.empty()
          ? 0.0
          : percentile({rss_after_warmup.end() - static_cast<std::ptrdiff_t>(quarter), rss_after_warmup.end()}, 0) -
                percentile({rss_after_warmup.begin(), rss_after_warmup.begin() + static_cast<std::ptrdiff_t>(quarter)},
                           0);
  PollerResult all;
  for (const auto& p : pollers) {
    all.reads += p.reads;
    all.failures += p.failures;
    all.heartbeat_backwards += p.heartbeat_backwards;
    all.longest_heartbeat_stand_s = std::max(all.longest_heartbeat_stand_s, p.longest_heartbeat_stand_s);
    all.latency_ms.insert(all.latency_ms.end(), p.latency_ms.begin(), p.latency_ms.end());
  }
  json j = {{"seconds", o.seconds},
            {"elapsed_s", elapsed_s},
            {"camera", o.camera},
            {"vision_ms", o.vision_ms},
            {"clients", o.clients},
            {"poll_ms", o.poll_ms},
            {"budget_ms", o.budget_ms},
            {"reads", all.reads},
            {"read_failures", all.failures},
            {"read_latency_ms",
             {{"p50", percentile(all.latency_ms, 50)},
              {"p99", percentile(all.latency_ms, 99)},
              {"max", percentile(all.latency_ms, 100)}}},
            {"heartbeat_backwards", all.heartbeat_backwards},
            {"heartbeat_longest_stand_s", all.longest_heartbeat_stand_s},
            {"jobs", plc.jobs},
            {"jobs_answered", plc.answered.load()},
            {"job_errors", plc.job_errors},
            {"lost_jobs", plc.lost_jobs},
            {"triggers_refused", plc.refused},
            {"picks", plc.picks},
            {"cycles_per_s", elapsed_s > 0 ? static_cast<double>(plc.answered.load()) / elapsed_s : 0.0},
            {"daemon_log", {{"errors", log_errors}, {"warnings", log_warnings}}},
            {"cycle_ms",
             {{"p50", percentile(plc.cycle_ms, 50)},
              {"p99", percentile(plc.cycle_ms, 99)},
              {"max", percentile(plc.cycle_ms, 100)}}},
            {"churn", o.churn},
            {"churn_failures", churn_failures.load()},
            {"reloads", reloads.load()},
            {"control_requests", control_requests.load()},
            {"control_failures", control_failures.load()},
            {"rss_kb",
             {{"first_sample", rss_first},
              {"after_warmup", rss_warm},
              {"end", rss_last},
              {"growth", rss_growth_kb},
              {"series", rss_series}}},
            {"fds", {{"before", fds_before}, {"after_warmup", fds_warm}, {"max", fds_max}, {"idle_after", fds_idle}}},
            {"daemon_alive", alive},
            {"exit_code", code ? *code : -1}};
  std::vector<std::string> failed;
  const auto check = [&](bool ok, const std::string& what) {
    if (!ok) failed.push_back(what);
  };
  check(alive && code && *code == 0, "the daemon ran to the end and stopped cleanly");
  check(all.failures == 0, "no failed read");
  check(all.heartbeat_backwards == 0 && all.longest_heartbeat_stand_s < o.max_heartbeat_stand_s,
        "HEARTBEAT monotone, never still for " + std::to_string(o.max_heartbeat_stand_s) + " s");
  check(plc.jobs > 0 && plc.job_errors == 0 && plc.lost_jobs == 0, "every job answered without error");
  check(o.jobs == 0 || plc.answered.load() >= o.jobs, "the --jobs count reached within --seconds");
  check(o.camera != "pattern" || plc.picks == plc.answered.load() - plc.job_errors,
        "pattern camera: every job carries the stand-in pick");
  check(log_errors == 0, "no error line in the daemon's log");
  check(percentile(plc.cycle_ms, 99) <= o.budget_ms, "cycle p99 within the budget");
  check(churn_failures == 0, "every churn connection served");
  check(control_failures == 0, "every control request answered");
  check(fds_idle >= 0 && fds_idle <= fds_before, "descriptors back to their count before the clients came");
  check(rss_growth_kb <= static_cast<double>(o.max_rss_growth_kb), "RSS growth within the limit");
  j["failed_checks"] = failed;
  const std::string text = j.dump(2);
  std::printf("%s\n", text.c_str());
  if (!o.json_file.empty()) std::ofstream(o.json_file) << text << "\n";
  std::printf("\n| figure | value |\n|---|---|\n");
  std::printf("| reads (%d clients every %d ms, %.0f s) | %ld, %ld failed |\n", o.clients, o.poll_ms, elapsed_s,
              all.reads, all.failures);
  std::printf("| read latency p50 / p99 / max | %.2f / %.2f / %.2f ms |\n", percentile(all.latency_ms, 50),
              percentile(all.latency_ms, 99), percentile(all.latency_ms, 100));
  std::printf("| camera; test backend work time | %s; %d ms |\n", o.camera.c_str(), o.vision_ms);
  std::printf("| jobs back to back | %ld, %ld errors, %ld lost; %ld with a pick |\n", plc.jobs, plc.job_errors,
              plc.lost_jobs, plc.picks);
  std::printf("| cycles per second | %.1f (%ld answered in %.0f s) |\n",
              elapsed_s > 0 ? static_cast<double>(plc.answered.load()) / elapsed_s : 0.0, plc.answered.load(),
              elapsed_s);
  std::printf("| daemon log | %ld error lines, %ld warning lines |\n", log_errors, log_warnings);
  std::printf("| cycle p50 / p99 / max (budget %d ms) | %.0f / %.0f / %.0f ms |\n", o.budget_ms,
              percentile(plc.cycle_ms, 50), percentile(plc.cycle_ms, 99), percentile(plc.cycle_ms, 100));
  std::printf("| HEARTBEAT longest stand | %.2f s |\n", all.longest_heartbeat_stand_s);
  std::printf("| churn connections | %d, %ld failed |\n", o.churn, churn_failures.load());
  if (o.sighup_ms > 0) std::printf("| reloads (SIGHUP every %d ms) | %ld |\n", o.sighup_ms, reloads.load());
  std::printf(
      "| daemon RSS first sample; after warm-up -> end; growth (median last - first quarter) | %ld; %ld -> %ld kB; "
      "%.0f kB |\n",
      rss_first, rss_warm, rss_last, rss_growth_kb);
  std::printf("| daemon fds before / after warm-up / max / idle after | %d / %d / %d / %d |\n", fds_before, fds_warm,
              fds_max, fds_idle);
  for (const auto& f : failed) std::printf("FAILED: %s\n", f.c_str());
  return failed.empty() ? 0 : 1;
}
