#pragma once
// Runs a real mfcd process (or mfcd_test_daemon) on a test configuration: port 0, control socket and
// snapshots in a fresh temporary directory; talks to its control socket; reads its stderr log.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/mount.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

extern char** environ;

namespace mfcd::daemon::test {

namespace fs = std::filesystem;
using nlohmann::json;

// The simulated cell with the six parts (meshes from <build>/parts), robot link on a free port.
inline std::string sim_cell_config(const fs::path& dir, int budget_ms = 1000, const std::string& extra_daemon = "",
                                   bool templates = false) {
  std::ostringstream s;
  s << "daemon:\n  cycle_budget_ms: " << budget_ms << "\n  control_socket: " << (dir / "ctl.sock").string()
    << "\n  lock_memory: false\n  realtime_priority: 0\n"
    << extra_daemon << "camera:\n  model: camera-sim.yaml\nsimulation:\n  parts_per_bin: 4\n  seed: 5\nrecipes:\n"
    << "  - {id: 0, part: any, obj_id: 0}\n";
  // In the order of config/parts/parts.csv: obj_id = position + 1.
  const char* parts[] = {"breaker", "diamond", "ellipse", "tnut", "knob", "wheel"};
  for (int i = 0; i < 6; ++i) {
    s << "  - {id: " << i + 1 << ", part: " << parts[i] << ", obj_id: " << i + 1 << ", mesh: parts/" << parts[i]
      << ".stl";
    if (templates) s << ", templates: templates/" << parts[i] << ".tdb";
    s << "}\n";
  }
  // A candidate's score is its fitted rank clamped to 0..1 (PoseCandidate::score): a correct match often scores
  // 0.2-0.4.
  s << "pick:\n  min_score: 0.1\n";
  s << "hand_eye:\n  base_T_camera: {x_mm: 500, y_mm: 0, z_mm: 800, rx_deg: 180, ry_deg: 0, rz_deg: 0}\n"
    << "modbus:\n  bind_address: 127.0.0.1\n  port: 0\n"
    << "snapshots:\n  directory: " << (dir / "snapshots").string() << "\n  quota_mb: 50\n  on_failure: false\n";
  return s.str();
}

// A small tmpfs mounted at `dir` (created) for a full-disk test; unmounted (lazily) when this
// goes. Mounting needs root, as CI runs: without it mounted() is false and the test skips with
// kSkipReason.
class SmallDisk {
 public:
  static constexpr const char* kSkipReason = "needs root to mount a small tmpfs (CI runs as root)";
  SmallDisk(const fs::path& dir, const std::string& size) : dir_(dir) {
    fs::create_directories(dir_);
    mounted_ = ::geteuid() == 0 && ::mount("tmpfs", dir_.c_str(), "tmpfs", 0, ("size=" + size).c_str()) == 0;
  }
  ~SmallDisk() {
    if (mounted_) ::umount2(dir_.c_str(), MNT_DETACH);
  }
  SmallDisk(const SmallDisk&) = delete;
  SmallDisk& operator=(const SmallDisk&) = delete;
  bool mounted() const { return mounted_; }
  const fs::path& dir() const { return dir_; }

 private:
  fs::path dir_;
  bool mounted_ = false;
};

// Sends raw bytes (one request line and its newline) and returns the reply line, without its
// newline; empty when the daemon does not answer.
inline std::string ctl_line(const fs::path& socket, const std::string& line, int timeout_ms = 30000) {
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::strncpy(addr.sun_path, socket.c_str(), sizeof addr.sun_path - 1);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    ::close(fd);
    return {};
  }
  ::send(fd, line.data(), line.size(), MSG_NOSIGNAL);
  std::string in;
  char buf[8192];
  while (in.find('\n') == std::string::npos) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, timeout_ms) <= 0) break;
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) break;
    in.append(buf, static_cast<std::size_t>(n));
  }
  ::close(fd);
  if (in.find('\n') == std::string::npos) return {};
  return in.substr(0, in.find('\n'));
}

inline json ctl_request(const fs::path& socket, const json& request, int timeout_ms = 30000) {
  const std::string reply = ctl_line(socket, request.dump() + "\n", timeout_ms);
  if (reply.empty()) return {{"ok", false}, {"error", "no answer"}};
  return json::parse(reply);
}

class DaemonProcess {
 public:
  explicit DaemonProcess(const std::string& name) {
    dir_ = fs::temp_directory_path() / ("mfcd-test-" + name + "-" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  ~DaemonProcess() {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
    fs::remove_all(dir_);
  }
  const fs::path& dir() const { return dir_; }
  fs::path socket() const { return dir_ / "ctl.sock"; }
  fs::path config_file() const { return dir_ / "mfcd.yaml"; }
  void write_config(const std::string& text) const { std::ofstream(config_file()) << text; }

  // Starts `binary -c mfcd.yaml -f [args]` with extra environment; stderr goes to log.txt.
  void start(const std::string& binary, std::vector<std::string> args = {}, std::vector<std::string> env = {}) {
    std::vector<std::string> argv{binary, "-c", config_file().string(), "-f"};
    argv.insert(argv.end(), args.begin(), args.end());
    std::vector<char*> a;
    for (auto& s : argv) a.push_back(s.data());
    a.push_back(nullptr);
    std::vector<std::string> envs;
    for (char** e = environ; *e; ++e) envs.emplace_back(*e);
    envs.insert(envs.end(), env.begin(), env.end());
    // Under the tsan preset, Mesa's uninstrumented llvmpipe threads need suppressing (tsan.supp).
    envs.emplace_back("TSAN_OPTIONS=suppressions=" MFC_SOURCE_DIR "/tests/daemon/tsan.supp halt_on_error=1");
    std::vector<char*> ev;
    for (auto& s : envs) ev.push_back(s.data());
    ev.push_back(nullptr);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 2, (dir_ / "log.txt").c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&fa, 1, (dir_ / "stdout.txt").c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::posix_spawn(&pid_, binary.c_str(), &fa, nullptr, a.data(), ev.data());
    posix_spawn_file_actions_destroy(&fa);
  }
  // Waits until the control socket answers status (the daemon is ready) or the process exits.
  bool wait_ready(int timeout_ms = 60000) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
    while (std::chrono::steady_clock::now() < end) {
      if (exited()) return false;
      if (fs::exists(socket())) {
        const json s = ctl({{"cmd", "status"}}, 2000);
        if (s.value("ok", false) && (s.value("state", "") == "ready" || s.value("state", "") == "busy")) return true;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return false;
  }
  json ctl(const json& request, int timeout_ms = 30000) const { return ctl_request(socket(), request, timeout_ms); }
  int modbus_port() const { return ctl({{"cmd", "status"}})["modbus"]["port"].get<int>(); }
  void signal(int sig) const { ::kill(pid_, sig); }
  pid_t pid() const { return pid_; }
  bool exited() {
    if (pid_ <= 0) return true;
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) == pid_) {
      exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      pid_ = -1;
      return true;
    }
    return false;
  }
  // Exit code, or nullopt if still running after timeout_ms.
  std::optional<int> wait(int timeout_ms) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
    while (std::chrono::steady_clock::now() < end) {
      if (exited()) return exit_code_;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return std::nullopt;
  }
  std::string log() const {
    std::ifstream in(dir_ / "log.txt");
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }
  std::string out() const {
    std::ifstream in(dir_ / "stdout.txt");
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }

 private:
  fs::path dir_;
  pid_t pid_ = -1;
  int exit_code_ = -1;
};

}  // namespace mfcd::daemon::test
