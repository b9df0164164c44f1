// mfcd-ctl: command-line client of mfcd's control socket (JSON lines; docs/operations.md).
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include <nlohmann/json.hpp>

namespace {

constexpr const char* kUsage =
    "usage: mfcd-ctl [-s SOCKET] [-t SECONDS] COMMAND [ARG]\n"
    "  status            daemon state, camera, vision backend, parts, Modbus clients\n"
    "  stats             cycle-time percentiles, overruns, detections, picks\n"
    "  last              the last cycle's result (candidates, pick, times, simulated ground truth)\n"
    "  trigger [RECIPE]  run one cycle now (not published to the PLC) and print its result\n"
    "  snapshot [RECIPE] run one cycle and save its images, depth edges, overlay and result.json\n"
    "  part RECIPE       select the recipe for trigger/snapshot and continuous mode\n"
    "  reload            reload the configuration and templates (like SIGHUP) and report the outcome\n"
    "  calibrate         calibration entry point (see docs/operations.md)\n"
    "SOCKET defaults to $MFCD_SOCKET, else /run/mfcd/control.sock. Exit status: 0 ok, 1 refused, 2 usage/connection.\n";

int usage() {
  std::fputs(kUsage, stderr);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::string socketPath = std::getenv("MFCD_SOCKET") ? std::getenv("MFCD_SOCKET") : "/run/mfcd/control.sock";
  int timeoutS = 60;
  int i = 1;
  for (; i < argc && argv[i][0] == '-'; ++i) {
    const std::string a = argv[i];
    if ((a == "-s" || a == "--socket") && i + 1 < argc) socketPath = argv[++i];
    else if ((a == "-t" || a == "--timeout") && i + 1 < argc) timeoutS = std::atoi(argv[++i]);
    else if (a == "-h" || a == "--help") { std::fputs(kUsage, stdout); return 0; }
    else return usage();
  }
  if (i >= argc) return usage();
  const std::string cmd = argv[i++];
  nlohmann::json req = {{"cmd", cmd}};
  if (cmd == "trigger" || cmd == "snapshot" || cmd == "part") {
    if (i < argc) {
      char* end = nullptr;
      const long r = std::strtol(argv[i], &end, 10);
      if (*end != '\0') return usage();
      req["recipe"] = r;
      ++i;
    } else if (cmd == "part") {
      return usage();
    }
  }
  if (i != argc) return usage();

  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (socketPath.size() >= sizeof addr.sun_path) {
    std::fprintf(stderr, "mfcd-ctl: socket path too long: %s\n", socketPath.c_str());
    return 2;
  }
  std::strncpy(addr.sun_path, socketPath.c_str(), sizeof addr.sun_path - 1);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    std::fprintf(stderr, "mfcd-ctl: cannot connect to %s: %s (is mfcd running? -s sets the socket)\n", socketPath.c_str(),
                 std::strerror(errno));
    return 2;
  }
  const std::string line = req.dump() + "\n";
  if (::send(fd, line.data(), line.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(line.size())) {
    std::fprintf(stderr, "mfcd-ctl: send to %s: %s\n", socketPath.c_str(), std::strerror(errno));
    return 2;
  }
  std::string in;
  char buf[8192];
  while (in.find('\n') == std::string::npos) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, timeoutS * 1000) <= 0) {
      std::fprintf(stderr, "mfcd-ctl: no answer from %s within %d s\n", socketPath.c_str(), timeoutS);
      return 2;
    }
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) {
      std::fprintf(stderr, "mfcd-ctl: %s closed the connection\n", socketPath.c_str());
      return 2;
    }
    in.append(buf, static_cast<std::size_t>(n));
  }
  ::close(fd);
  nlohmann::json rsp;
  try {
    rsp = nlohmann::json::parse(in.substr(0, in.find('\n')));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mfcd-ctl: unreadable answer: %s\n", e.what());
    return 2;
  }
  std::printf("%s\n", rsp.dump(2).c_str());
  return rsp.value("ok", false) ? 0 : 1;
}
