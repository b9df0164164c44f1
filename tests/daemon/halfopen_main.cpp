// mfcd_halfopen: half-open Modbus peers made by a firewall drop in a network namespace, against the
// real daemon (mfcd_test_daemon on the simulated cell). Driven by halfopen_netns.sh, which creates
// the namespace and the veth pair (and removes them on every exit path); this program never creates
// or deletes either.
//
//   mfcd_halfopen run --daemon PATH --netns NS --host-addr H --holder-addr A --plc-addr B
//   mfcd_halfopen hold --server H --port P --source A --connections N [--mid-frame]   (inside NS)
//   mfcd_halfopen plc --server H --port P --source B --within-s S                     (inside NS)
//
// `run` starts the daemon bound to H (the veth's host end) with max_clients 4 and checks, twice:
//   1. idle peers: `hold` fills every slot from A (one answered read per connection, then silence);
//      nft inside NS drops all traffic of A both ways, so the daemon's four connections turn half-open
//      (no FIN, no RST can reach it). A new PLC from B (the same veth, another address) must be served
//      (a read and a whole TRIGGER job) within 30 s: the server evicts the idle-longest client. The
//      other three must then be closed by the server's TCP keepalive / TCP_USER_TIMEOUT (5 s idle +
//      3 probes 2 s apart, 10 s: motion/modbus_server.hpp) within 30 s of the drop, counted as dropped,
//      while the holder is still alive and its side still shows them ESTABLISHED (the half-open
//      state). idle_timeout_ms stays at 60000 (the default): longer than the window, so the idle
//      timeout cannot be what frees them; without the drop the probes are answered and the
//      connections would stay.
//   2. mid-frame peers: `hold --mid-frame` fills every slot and leaves each 3 bytes into an MBAP
//      header, then the same drop. No slot can be evicted (all mid-frame), so the PLC is refused
//      until frame_timeout_ms (5000 here, above the default 2000 so the refusal is seen on a slow
//      machine) closes them; it must then be served within 30 s of the drop.
// After each phase the daemon's open descriptors (/proc/PID/fd) must be back to their count before
// the holder connected. Exit 0 when every check holds, 1 when one fails, 77 when the simulated cell
// cannot run here (no offscreen OpenGL).
#include <arpa/inet.h>
#include <fcntl.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <map>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "base/unique_fd.hpp"
#include "daemon_process.hpp"
#include "motion/register_map.hpp"

using namespace mfcd::daemon::test;
namespace reg = mfcd::motion::reg;
using mfcd::UniqueFd;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

namespace {

constexpr int kMaxClients = 4;
constexpr int kFrameTimeoutMs = 5000;
constexpr int kIdleTimeoutMs = 60000;
constexpr double kWithinS = 30.0;  // the bound: the PLC is back within 30 s

double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

std::map<std::string, std::string> parse_options(int argc, char** argv, int first) {
  std::map<std::string, std::string> o;
  for (int i = first; i < argc; ++i) {
    const std::string a = argv[i];
    if (a.rfind("--", 0) != 0) throw std::invalid_argument("unexpected argument " + a);
    if (a == "--mid-frame") {
      o[a] = "1";
      continue;
    }
    if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
    o[a] = argv[++i];
  }
  return o;
}

std::string need(const std::map<std::string, std::string>& o, const std::string& key) {
  const auto it = o.find(key);
  if (it == o.end()) throw std::invalid_argument(key + " is required");
  return it->second;
}

// A TCP connection from `source` (bound, so the firewall rule can single it out) to server:port, or
// an invalid fd. connect() is bounded by `timeout_ms`.
UniqueFd connect_from(const std::string& source, const std::string& server, int port, int timeout_ms) {
  UniqueFd fd(::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0));
  sockaddr_in src{}, dst{};
  src.sin_family = dst.sin_family = AF_INET;
  dst.sin_port = htons(static_cast<std::uint16_t>(port));
  if (inet_pton(AF_INET, source.c_str(), &src.sin_addr) != 1 || inet_pton(AF_INET, server.c_str(), &dst.sin_addr) != 1)
    throw std::invalid_argument("not an IPv4 address: " + source + " / " + server);
  if (::bind(fd.get(), reinterpret_cast<sockaddr*>(&src), sizeof src) != 0) return {};
  if (::connect(fd.get(), reinterpret_cast<sockaddr*>(&dst), sizeof dst) != 0) {
    if (errno != EINPROGRESS) return {};
    pollfd p{fd.get(), POLLOUT, 0};
    int err = 0;
    socklen_t len = sizeof err;
    if (::poll(&p, 1, timeout_ms) != 1 || ::getsockopt(fd.get(), SOL_SOCKET, SO_ERROR, &err, &len) != 0 || err != 0)
      return {};
  }
  const int flags = ::fcntl(fd.get(), F_GETFL);
  ::fcntl(fd.get(), F_SETFL, flags & ~O_NONBLOCK);  // libmodbus expects a blocking socket
  return fd;
}

// libmodbus over a socket this program connected (libmodbus cannot bind a source address itself).
// The context does not own the socket: modbus_close() is never called on it.
struct Modbus {
  explicit Modbus(int fd) : ctx(modbus_new_tcp("127.0.0.1", 502)) {
    modbus_set_socket(ctx, fd);
    modbus_set_response_timeout(ctx, 2, 0);
  }
  ~Modbus() { modbus_free(ctx); }
  Modbus(const Modbus&) = delete;
  Modbus& operator=(const Modbus&) = delete;
  bool read_status(std::uint16_t (&regs)[28]) { return modbus_read_registers(ctx, reg::kStatus, 28, regs) == 28; }
  modbus_t* ctx;
};

// --- inside the namespace ---------------------------------------------------------------------

// Opens N connections from `source`, each answered once (a read of the status block); with
// --mid-frame each then gets the first 3 bytes of an MBAP header. Prints "held N" and keeps the
// connections, silent, until its stdin reaches EOF (the `run` process closed it or died).
int hold_main(const std::map<std::string, std::string>& o) {
  const std::string server = need(o, "--server"), source = need(o, "--source");
  const int port = std::stoi(need(o, "--port")), n = std::stoi(need(o, "--connections"));
  const bool mid_frame = o.count("--mid-frame") != 0;
  std::vector<UniqueFd> held;
  for (int i = 0; i < n; ++i) {
    UniqueFd fd = connect_from(source, server, port, 5000);
    if (!fd) {
      std::fprintf(stderr, "hold: connection %d from %s to %s:%d failed: %s\n", i, source.c_str(), server.c_str(), port,
                   std::strerror(errno));
      return 1;
    }
    std::uint16_t regs[28];
    if (!Modbus(fd.get()).read_status(regs)) {
      std::fprintf(stderr, "hold: connection %d was not served: %s\n", i, modbus_strerror(errno));
      return 1;
    }
    held.push_back(std::move(fd));
  }
  if (mid_frame)
    for (auto& fd : held) {
      const std::uint8_t part[3] = {0x12, 0x34, 0x00};  // transaction id, first byte of the protocol id
      if (::send(fd.get(), part, sizeof part, MSG_NOSIGNAL) != sizeof part) return 1;
    }
  std::printf("held %d\n", n);
  std::fflush(stdout);
  char c;
  while (::read(0, &c, 1) > 0) {
  }
  return 0;
}

// A PLC that (re)connects from `source` until it is served: a read of the status block, then a
// whole job (TRIGGER, JOB_ID_ECHO, ERROR_CODE 0). Prints one JSON line {served, after_s, attempts,
// refused}; exit 0 when served within --within-s.
int plc_main(const std::map<std::string, std::string>& o) {
  const std::string server = need(o, "--server"), source = need(o, "--source");
  const int port = std::stoi(need(o, "--port"));
  const double within_s = std::stod(need(o, "--within-s"));
  const auto start = Clock::now();
  int attempts = 0, refused = 0;
  bool served = false;
  std::string why = "never tried";
  while (!served && seconds_since(start) < within_s) {
    ++attempts;
    UniqueFd fd = connect_from(source, server, port, 2000);
    if (!fd) {
      why = std::string("connect: ") + std::strerror(errno);
      std::this_thread::sleep_for(200ms);
      continue;
    }
    Modbus m(fd.get());
    std::uint16_t regs[28];
    if (!m.read_status(regs)) {
      // Accepted and closed at once: the server had no slot for it.
      ++refused;
      why = std::string("read: ") + modbus_strerror(errno);
      std::this_thread::sleep_for(200ms);
      continue;
    }
    const std::uint16_t job = static_cast<std::uint16_t>(1000 + attempts);
    const auto job_end = Clock::now() + 20s;
    while (!(regs[0] & reg::kReady) && Clock::now() < job_end) {
      std::this_thread::sleep_for(20ms);
      m.read_status(regs);
    }
    const std::uint16_t cmd[4] = {1, job, 0, 0};
    if (modbus_write_registers(m.ctx, reg::kCommand, 4, cmd) != 4) {
      why = std::string("trigger: ") + modbus_strerror(errno);
      break;
    }
    while (Clock::now() < job_end) {
      if (m.read_status(regs) && regs[reg::kJobIdEcho - reg::kStatus] == job) break;
      std::this_thread::sleep_for(10ms);
    }
    if (regs[reg::kJobIdEcho - reg::kStatus] != job) {
      why = "job " + std::to_string(job) + " not answered within 20 s";
      break;
    }
    if (regs[reg::kErrorCode - reg::kStatus] != 0) {
      why = "job " + std::to_string(job) + " answered with error code " +
            std::to_string(regs[reg::kErrorCode - reg::kStatus]);
      break;
    }
    served = true;
  }
  const json line = {{"served", served},
                     {"after_s", seconds_since(start)},
                     {"attempts", attempts},
                     {"refused", refused},
                     {"why", served ? "" : why}};
  std::printf("%s\n", line.dump().c_str());
  return served ? 0 : 1;
}

// --- the test itself, in the host's namespace -----------------------------------------------------

int fd_count(pid_t pid) {
  int n = 0;
  std::error_code ec;
  for (auto it = fs::directory_iterator("/proc/" + std::to_string(pid) + "/fd", ec);
       !ec && it != fs::directory_iterator(); ++it)
    ++n;
  return n;
}

// Runs a shell command; returns its exit status and appends its output (stdout and stderr).
int shell(const std::string& command, std::string* output = nullptr) {
  FILE* p = ::popen((command + " 2>&1").c_str(), "r");
  if (!p) return -1;
  char buf[4096];
  std::string out;
  while (std::fgets(buf, sizeof buf, p)) out += buf;
  const int status = ::pclose(p);
  if (output) *output = out;
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128;
}

// A child process with its stdin and stdout on pipes; stdin closed (EOF) and the child reaped when
// this object goes, SIGKILL after 3 s if it has not exited by then.
class Child {
 public:
  explicit Child(const std::vector<std::string>& argv) {
    int in[2], out[2];
    if (::pipe2(in, O_CLOEXEC) != 0 || ::pipe2(out, O_CLOEXEC) != 0) throw std::runtime_error("pipe2 failed");
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_adddup2(&fa, in[0], 0);
    posix_spawn_file_actions_adddup2(&fa, out[1], 1);
    std::vector<char*> a;
    for (const auto& s : argv) a.push_back(const_cast<char*>(s.c_str()));
    a.push_back(nullptr);
    const int rc = ::posix_spawnp(&pid_, a[0], &fa, nullptr, a.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    ::close(in[0]);
    ::close(out[1]);
    stdin_.reset(in[1]);
    stdout_.reset(out[0]);
    if (rc != 0) {
      pid_ = -1;
      throw std::runtime_error("cannot start " + argv[0] + ": " + std::strerror(rc));
    }
  }
  ~Child() {
    stdin_.reset();
    if (pid_ > 0 && !wait_exit(3000)) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;
  // One line of its stdout (without the newline), or empty after `timeout_ms` or EOF.
  std::string read_line(int timeout_ms) {
    const auto end = Clock::now() + std::chrono::milliseconds(timeout_ms);
    while (buffer_.find('\n') == std::string::npos) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(end - Clock::now()).count();
      pollfd p{stdout_.get(), POLLIN, 0};
      if (left <= 0 || ::poll(&p, 1, static_cast<int>(left)) <= 0) return {};
      char buf[512];
      const ssize_t n = ::read(stdout_.get(), buf, sizeof buf);
      if (n <= 0) return {};
      buffer_.append(buf, static_cast<std::size_t>(n));
    }
    const std::string line = buffer_.substr(0, buffer_.find('\n'));
    buffer_.erase(0, line.size() + 1);
    return line;
  }
  bool running() {
    if (pid_ <= 0) return false;
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) == pid_) {
      exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      pid_ = -1;
      return false;
    }
    return true;
  }
  bool wait_exit(int timeout_ms) {
    const auto end = Clock::now() + std::chrono::milliseconds(timeout_ms);
    while (running()) {
      if (Clock::now() >= end) return false;
      std::this_thread::sleep_for(20ms);
    }
    return true;
  }
  int exit_code() const { return exit_code_; }
  void close_stdin() { stdin_.reset(); }

 private:
  pid_t pid_ = -1;
  int exit_code_ = -1;
  UniqueFd stdin_, stdout_;
  std::string buffer_;
};

struct Checks {
  std::vector<std::string> failed;
  void operator()(bool ok, const std::string& what) {
    std::printf("%s: %s\n", ok ? "ok    " : "FAILED", what.c_str());
    if (!ok) failed.push_back(what);
  }
};

struct LinkStats {
  int clients = -1;
  long evicted = -1, dropped = -1, idle_closed = -1;
};

LinkStats link_stats(const DaemonProcess& proc) {
  const json s = proc.ctl({{"cmd", "status"}}, 5000);
  LinkStats l;
  if (!s.contains("modbus")) return l;
  const json& m = s["modbus"];
  l.clients = m.value("clients", -1);
  l.evicted = m.value("evicted", -1L);
  l.dropped = m.value("dropped", -1L);
  l.idle_closed = m.value("idle_closed", -1L);
  return l;
}

// ESTABLISHED TCP connections from `source` to server:port as the namespace's kernel sees them.
int established_in_netns(const std::string& netns, const std::string& source, const std::string& server, int port) {
  std::string out;
  shell("ip netns exec " + netns + " ss -Htn state established src " + source + " dst " + server + ":" +
            std::to_string(port),
        &out);
  int n = 0;
  for (char c : out) n += c == '\n';
  return n;
}

struct Setup {
  std::string self, netns, host, holder_addr, plc_addr;
  int port = 0;
};

std::vector<std::string> in_netns(const Setup& s, std::vector<std::string> args) {
  std::vector<std::string> argv{"ip", "netns", "exec", s.netns, s.self};
  argv.insert(argv.end(), args.begin(), args.end());
  return argv;
}

// Both directions of the holder's address, inside the namespace (so the host is not touched); the
// table goes with the namespace at the latest.
bool drop_holder(const Setup& s, std::string& error) {
  const std::string rules =
      "table inet mfcd_halfopen {\n"
      "  chain in { type filter hook input priority 0; policy accept; ip daddr " +
      s.holder_addr +
      " drop; }\n"
      "  chain out { type filter hook output priority 0; policy accept; ip saddr " +
      s.holder_addr +
      " drop; }\n"
      "}\n";
  const fs::path file = fs::temp_directory_path() / ("mfcd-halfopen-" + std::to_string(::getpid()) + ".nft");
  std::ofstream(file) << rules;
  const int rc = shell("ip netns exec " + s.netns + " nft -f " + file.string(), &error);
  fs::remove(file);
  return rc == 0;
}

void lift_drop(const Setup& s) { shell("ip netns exec " + s.netns + " nft delete table inet mfcd_halfopen"); }

// Waits until the daemon reports `clients` Modbus clients; the seconds that took, or -1 after `limit_s`.
double wait_clients(const DaemonProcess& proc, int clients, Clock::time_point since, double limit_s) {
  while (seconds_since(since) < limit_s) {
    if (link_stats(proc).clients == clients) return seconds_since(since);
    std::this_thread::sleep_for(100ms);
  }
  return -1;
}

// The daemon's descriptor count once it holds still: the same over three readings 100 ms apart
// (a control-socket client, e.g. this program's own status request, is closed by the daemon a
// moment after the request has been answered).
int settled_fd_count(pid_t pid) {
  int n = fd_count(pid), same = 0;
  for (int i = 0; i < 50 && same < 2; ++i) {
    std::this_thread::sleep_for(100ms);
    const int m = fd_count(pid);
    same = m == n ? same + 1 : 0;
    n = m;
  }
  return n;
}

// Waits until the daemon's descriptor count is `want` (a closed connection's fd, and that of the
// status request just made, go a moment later); the last count seen.
int wait_fds(pid_t pid, int want, double limit_s) {
  const auto start = Clock::now();
  int n = fd_count(pid);
  while (n != want && seconds_since(start) < limit_s) {
    std::this_thread::sleep_for(100ms);
    n = fd_count(pid);
  }
  return n;
}

json run_plc(const Setup& s) {
  Child plc(in_netns(s, {"plc", "--server", s.host, "--port", std::to_string(s.port), "--source", s.plc_addr,
                         "--within-s", std::to_string(kWithinS)}));
  const std::string line = plc.read_line(static_cast<int>(kWithinS * 1000) + 25000);
  try {
    return json::parse(line);
  } catch (const std::exception&) {
    return {{"served", false}, {"why", "no report from the PLC process: '" + line + "'"}};
  }
}

void phase_idle(const Setup& s, DaemonProcess& proc, int fds_before, Checks& check) {
  std::printf("--- phase 1: %d idle peers made half-open; the PLC reconnects from %s\n", kMaxClients,
              s.plc_addr.c_str());
  Child holder(in_netns(s, {"hold", "--server", s.host, "--port", std::to_string(s.port), "--source", s.holder_addr,
                            "--connections", std::to_string(kMaxClients)}));
  const std::string held = holder.read_line(15000);
  check(held == "held " + std::to_string(kMaxClients),
        "the holder's " + std::to_string(kMaxClients) + " connections were served ('" + held + "')");
  if (held.empty()) return;
  const LinkStats before = link_stats(proc);
  check(before.clients == kMaxClients, "every slot taken: " + std::to_string(before.clients) + " clients");
  const int fds_held = wait_fds(proc.pid(), fds_before + kMaxClients, 3);
  check(fds_held == fds_before + kMaxClients, "one descriptor per held connection (" + std::to_string(fds_held) + ")");
  std::string error;
  const bool dropped = drop_holder(s, error);
  check(dropped, "nft drop rule for " + s.holder_addr + " in " + s.netns + (dropped ? "" : ": " + error));
  if (!dropped) return;
  const auto t_drop = Clock::now();

  const json plc = run_plc(s);
  const double served_at = seconds_since(t_drop);
  std::printf("PLC: %s\n", plc.dump().c_str());
  check(plc.value("served", false) && served_at <= kWithinS,
        "the PLC was served (a read and a whole job) within " + std::to_string(served_at) + " s of the drop (<= 30 s)");
  const LinkStats after_plc = link_stats(proc);
  check(after_plc.evicted == before.evicted + 1, "it took the slot of the idle-longest half-open peer (evicted +" +
                                                     std::to_string(after_plc.evicted - before.evicted) + ")");

  // The PLC has left; the other three half-open peers must go by keepalive / TCP_USER_TIMEOUT.
  const double gone_s = wait_clients(proc, 0, t_drop, kWithinS);
  std::printf("half-open peers closed by the server %.1f s after the drop\n", gone_s);
  check(gone_s >= 0, "the remaining half-open peers were closed within 30 s of the drop");
  const LinkStats after = link_stats(proc);
  check(after.dropped - before.dropped == kMaxClients - 1, "closed as dead (keepalive / user timeout: dropped +" +
                                                               std::to_string(after.dropped - before.dropped) +
                                                               ", want +" + std::to_string(kMaxClients - 1) + ")");
  check(after.idle_closed == before.idle_closed, "not by the idle timeout (idle_closed unchanged)");
  const bool holder_alive = holder.running();
  const int still_established = established_in_netns(s.netns, s.holder_addr, s.host, s.port);
  check(holder_alive && still_established == kMaxClients, "half-open: the holder is alive and its side still has " +
                                                              std::to_string(still_established) + " of " +
                                                              std::to_string(kMaxClients) + " connections ESTABLISHED");
  const int fds = wait_fds(proc.pid(), fds_before, 5);
  check(fds == fds_before,
        "daemon descriptors back to " + std::to_string(fds_before) + " (now " + std::to_string(fds) + ")");
  holder.close_stdin();
  check(holder.wait_exit(5000) && holder.exit_code() == 0, "the holder ended cleanly");
  lift_drop(s);
}

void phase_mid_frame(const Setup& s, DaemonProcess& proc, int fds_before, Checks& check) {
  std::printf("--- phase 2: %d peers made half-open in the middle of a frame\n", kMaxClients);
  Child holder(in_netns(s, {"hold", "--server", s.host, "--port", std::to_string(s.port), "--source", s.holder_addr,
                            "--connections", std::to_string(kMaxClients), "--mid-frame"}));
  const std::string held = holder.read_line(15000);
  check(held == "held " + std::to_string(kMaxClients),
        "the holder's mid-frame connections were served ('" + held + "')");
  if (held.empty()) return;
  const LinkStats before = link_stats(proc);
  check(before.clients == kMaxClients,
        "every slot taken, each mid-frame: " + std::to_string(before.clients) + " clients");
  std::string error;
  const bool dropped = drop_holder(s, error);
  check(dropped, "nft drop rule" + (dropped ? "" : ": " + error));
  if (!dropped) return;
  const auto t_drop = Clock::now();
  const json plc = run_plc(s);
  const double served_at = seconds_since(t_drop);
  std::printf("PLC: %s\n", plc.dump().c_str());
  check(plc.value("served", false) && served_at <= kWithinS,
        "the PLC was served " + std::to_string(served_at) + " s after the drop (<= 30 s)");
  check(plc.value("refused", 0) >= 1, "it was refused while every slot was mid-frame (" +
                                          std::to_string(plc.value("refused", 0)) + " refusals; frame_timeout_ms " +
                                          std::to_string(kFrameTimeoutMs) + ")");
  const double gone_s = wait_clients(proc, 0, t_drop, kWithinS);
  check(gone_s >= 0, "every mid-frame half-open peer closed");
  const LinkStats after = link_stats(proc);
  check(after.dropped - before.dropped == kMaxClients,
        "closed by the frame timeout (dropped +" + std::to_string(after.dropped - before.dropped) +
            "), none evicted (+" + std::to_string(after.evicted - before.evicted) + ")");
  check(after.evicted == before.evicted, "no mid-frame client was evicted");
  const int fds = wait_fds(proc.pid(), fds_before, 5);
  check(fds == fds_before,
        "daemon descriptors back to " + std::to_string(fds_before) + " (now " + std::to_string(fds) + ")");
  holder.close_stdin();
  check(holder.wait_exit(5000) && holder.exit_code() == 0, "the holder ended cleanly");
  lift_drop(s);
}

// The daemon of `run`, for the signal handler: SIGTERM/SIGINT/SIGHUP (the driver's trap, a ctest
// timeout, ^C) end it before this process goes, so no daemon outlives the test. Clients inside the
// namespace end on their stdin's EOF, or by the driver's trap.
volatile sig_atomic_t g_daemon_pid = 0;

extern "C" void on_terminate(int sig) {
  if (g_daemon_pid > 0) ::kill(static_cast<pid_t>(g_daemon_pid), SIGKILL);
  ::_exit(128 + sig);
}

int run_main(const std::map<std::string, std::string>& o) {
  Setup s;
  s.self = fs::canonical("/proc/self/exe").string();
  s.netns = need(o, "--netns");
  s.host = need(o, "--host-addr");
  s.holder_addr = need(o, "--holder-addr");
  s.plc_addr = need(o, "--plc-addr");

  DaemonProcess proc("halfopen");
  std::string config = sim_cell_config(proc.dir());
  const std::string modbus = "modbus:\n  bind_address: 127.0.0.1\n  port: 0\n";
  config.replace(config.find(modbus), modbus.size(),
                 "modbus:\n  bind_address: " + s.host + "\n  port: 0\n  max_clients: " + std::to_string(kMaxClients) +
                     "\n  frame_timeout_ms: " + std::to_string(kFrameTimeoutMs) +
                     "\n  idle_timeout_ms: " + std::to_string(kIdleTimeoutMs) + "\n");
  proc.write_config(config);
  for (int sig : {SIGTERM, SIGINT, SIGHUP}) ::signal(sig, on_terminate);
  proc.start(need(o, "--daemon"));
  g_daemon_pid = proc.pid();
  if (!proc.wait_ready()) {
    const std::string log = proc.log();
    std::fprintf(stderr, "mfcd did not become ready:\n%s\n", log.c_str());
    return log.find("EGL") != std::string::npos || log.find("OpenGL") != std::string::npos ? 77 : 1;
  }
  s.port = proc.modbus_port();
  const int fds_before = settled_fd_count(proc.pid());
  std::printf("daemon pid %d on %s:%d, %d descriptors; max_clients %d, frame_timeout_ms %d, idle_timeout_ms %d\n",
              proc.pid(), s.host.c_str(), s.port, fds_before, kMaxClients, kFrameTimeoutMs, kIdleTimeoutMs);
  Checks check;
  phase_idle(s, proc, fds_before, check);
  phase_mid_frame(s, proc, fds_before, check);
  proc.signal(SIGTERM);
  const auto code = proc.wait(30000);
  if (code) g_daemon_pid = 0;
  check(code && *code == 0, "the daemon stopped cleanly");
  if (!check.failed.empty()) {
    std::printf("%zu check(s) failed; the daemon's log:\n%s\n", check.failed.size(), proc.log().c_str());
    return 1;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  std::setvbuf(stdout, nullptr, _IOLBF, 0);  // each check's line reaches the ctest log at once
  try {
    const std::string mode = argc > 1 ? argv[1] : "";
    if (mode == "run") return run_main(parse_options(argc, argv, 2));
    if (mode == "hold") return hold_main(parse_options(argc, argv, 2));
    if (mode == "plc") return plc_main(parse_options(argc, argv, 2));
    std::fprintf(stderr, "usage: mfcd_halfopen run|hold|plc [options] (see tests/daemon/halfopen_main.cpp)\n");
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mfcd_halfopen: %s\n", e.what());
    return 1;
  }
}
