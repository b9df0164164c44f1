// mfcd-ctl: command-line client of mfcd's control socket (JSON lines; docs/operations.md).
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cmath>
#include <cstring>
#include <iostream>
#include <sstream>
#include <optional>
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
    "  calibrate intrinsics start             start a camera intrinsics session (picking pauses)\n"
    "  calibrate hand-eye start [--mode eye-to-hand|eye-in-hand]   start a hand-eye session\n"
    "  calibrate capture [--pose x,y,z,rx,ry,rz | --pose-from-plc] [--sim-plate-pose x,y,z,rx,ry,rz]\n"
    "                    grab the next frame set's ambient image as a view (hand-eye: with the flange pose)\n"
    "  calibrate compute                      compute and show the figures (nothing is written)\n"
    "  calibrate check --pose ... | --pose-from-plc   hand-eye: predicted vs seen board in a new view\n"
    "  calibrate apply [--yes]                write the camera file (keeps .previous) and reload\n"
    "  calibrate rollback [--yes]             restore the camera file's .previous and reload\n"
    "  calibrate abort | status               end the session without writing | show it\n"
    "SOCKET defaults to $MFCD_SOCKET, else /run/mfcd/control.sock. Exit status: 0 ok, 1 refused, 2 usage/connection.\n";

int usage() {
  std::fputs(kUsage, stderr);
  return 2;
}

// "x,y,z,rx,ry,rz" -> six finite numbers, or throws naming the option.
nlohmann::json parsePose(const std::string& text, const std::string& option) {
  nlohmann::json out = nlohmann::json::array();
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    char* end = nullptr;
    const double v = std::strtod(item.c_str(), &end);
    if (item.empty() || *end != '\0' || !std::isfinite(v))
      throw std::invalid_argument(option + " '" + text + "': '" + item + "' is not a number");
    out.push_back(v);
  }
  if (out.size() != 6)
    throw std::invalid_argument(option + " '" + text + "': expected x,y,z,rx,ry,rz (mm, degrees), got " +
                                std::to_string(out.size()) + " numbers");
  return out;
}

struct Connection {
  std::string socketPath;
  int timeoutS;
};

// Sends one request line and returns the answer; nullopt (message printed) on connection trouble.
std::optional<nlohmann::json> roundTrip(const Connection& conn, const nlohmann::json& req) {
  const std::string& socketPath = conn.socketPath;
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (socketPath.size() >= sizeof addr.sun_path) {
    std::fprintf(stderr, "mfcd-ctl: socket path too long: %s\n", socketPath.c_str());
    return std::nullopt;
  }
  std::strncpy(addr.sun_path, socketPath.c_str(), sizeof addr.sun_path - 1);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    std::fprintf(stderr, "mfcd-ctl: cannot connect to %s: %s (is mfcd running? -s sets the socket)\n", socketPath.c_str(),
                 std::strerror(errno));
    ::close(fd);
    return std::nullopt;
  }
  const std::string line = req.dump() + "\n";
  if (::send(fd, line.data(), line.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(line.size())) {
    std::fprintf(stderr, "mfcd-ctl: send to %s: %s\n", socketPath.c_str(), std::strerror(errno));
    ::close(fd);
    return std::nullopt;
  }
  std::string in;
  char buf[8192];
  while (in.find('\n') == std::string::npos) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, conn.timeoutS * 1000) <= 0) {
      std::fprintf(stderr, "mfcd-ctl: no answer from %s within %d s\n", socketPath.c_str(), conn.timeoutS);
      ::close(fd);
      return std::nullopt;
    }
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) {
      std::fprintf(stderr, "mfcd-ctl: %s closed the connection\n", socketPath.c_str());
      ::close(fd);
      return std::nullopt;
    }
    in.append(buf, static_cast<std::size_t>(n));
  }
  ::close(fd);
  try {
    return nlohmann::json::parse(in.substr(0, in.find('\n')));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mfcd-ctl: unreadable answer: %s\n", e.what());
    return std::nullopt;
  }
}

// mfcd-ctl calibrate ...: builds the request; apply/rollback without --yes ask on a terminal.
// Returns nullopt after printing usage (exit 2) or when the operator declined (exit 1, `declined`).
std::optional<nlohmann::json> calibrateRequest(int argc, char** argv, int i, const Connection& conn, bool& declined) {
  nlohmann::json req = {{"cmd", "calibrate"}};
  if (i >= argc) return std::nullopt;
  std::string first = argv[i++];
  if (first == "intrinsics" || first == "hand-eye") {
    if (i >= argc || std::string(argv[i]) != "start") return std::nullopt;
    ++i;
    req["action"] = "start";
    req["kind"] = first;
  } else {
    req["action"] = first;
  }
  const std::string action = req["action"];
  bool yes = false;
  for (; i < argc; ++i) {
    const std::string a = argv[i];
    const bool hasValue = i + 1 < argc;
    if (a == "--mode" && hasValue && req.value("kind", "") == "hand-eye") req["mode"] = argv[++i];
    else if (a == "--pose" && hasValue && (action == "capture" || action == "check")) req["pose"] = parsePose(argv[++i], a);
    else if (a == "--pose-from-plc" && (action == "capture" || action == "check")) req["pose_from_plc"] = true;
    else if (a == "--sim-plate-pose" && hasValue && action == "capture") req["sim_plate_pose"] = parsePose(argv[++i], a);
    else if ((a == "--yes" || a == "-y") && (action == "apply" || action == "rollback")) yes = true;
    else {
      std::fprintf(stderr, "mfcd-ctl: calibrate %s: unexpected '%s'\n", action.c_str(), a.c_str());
      return std::nullopt;
    }
  }
  if (action == "apply" || action == "rollback") {
    if (!yes) {
      if (!::isatty(STDIN_FILENO)) {
        std::fprintf(stderr, "mfcd-ctl: calibrate %s changes the camera file: give --yes (no terminal to ask on)\n",
                     action.c_str());
        declined = true;
        return std::nullopt;
      }
      // Show what would be written before asking.
      if (const auto s = roundTrip(conn, {{"cmd", "calibrate"}, {"action", "status"}})) {
        const auto& session = (*s)["session"];
        if (action == "apply" && session.value("figures", "") != "") std::printf("%s\n", session.value("figures", "").c_str());
        std::printf("%s %s? [y/N] ", action == "apply" ? "write" : "restore the previous", s->value("camera_file", "the camera file").c_str());
      } else {
        declined = true;
        return std::nullopt;
      }
      std::fflush(stdout);
      std::string answer;
      std::getline(std::cin, answer);
      if (answer != "y" && answer != "Y" && answer != "yes") {
        std::printf("nothing written\n");
        declined = true;
        return std::nullopt;
      }
    }
    req["confirm"] = true;
  }
  return req;
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
  const Connection conn{socketPath, timeoutS};
  nlohmann::json req = {{"cmd", cmd}};
  if (cmd == "calibrate") {
    bool declined = false;
    std::optional<nlohmann::json> r;
    try {
      r = calibrateRequest(argc, argv, i, conn, declined);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "mfcd-ctl: %s\n", e.what());
      return 2;
    }
    if (!r) return declined ? 1 : usage();
    req = *r;
    i = argc;
  }
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

  const auto rsp = roundTrip(conn, req);
  if (!rsp) return 2;
  // Calibration figures are a table for people: printed as they are, then the whole answer.
  if (cmd == "calibrate" && rsp->contains("figures") && (*rsp)["figures"].is_string())
    std::printf("%s\n", (*rsp)["figures"].get<std::string>().c_str());
  std::printf("%s\n", rsp->dump(2).c_str());
  return rsp->value("ok", false) ? 0 : 1;
}
