// mfcd-ctl: command-line client of mfcd's control socket (JSON lines; docs/operations.md).
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "base/unique_fd.hpp"
#include "tools/common/cli.hpp"

namespace {

// "x,y,z,rx,ry,rz" -> six finite numbers, or throws naming the option.
nlohmann::json parse_pose(const std::string& text, const std::string& option) {
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
  std::string socket_path;
  int timeout_s;
};

// Sends one request line and returns the answer; nullopt (message printed) on connection trouble.
std::optional<nlohmann::json> round_trip(const Connection& conn, const nlohmann::json& req) {
  const std::string& socket_path = conn.socket_path;
  const mfcd::UniqueFd connection(::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0));
  const int fd = connection.get();
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (socket_path.size() >= sizeof addr.sun_path) {
    std::fprintf(stderr, "mfcd-ctl: socket path too long: %s\n", socket_path.c_str());
    return std::nullopt;
  }
  std::strncpy(addr.sun_path, socket_path.c_str(), sizeof addr.sun_path - 1);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    std::fprintf(stderr, "mfcd-ctl: cannot connect to %s: %s (is mfcd running? -s sets the socket)\n",
                 socket_path.c_str(), std::strerror(errno));
    return std::nullopt;
  }
  const std::string line = req.dump() + "\n";
  if (::send(fd, line.data(), line.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(line.size())) {
    std::fprintf(stderr, "mfcd-ctl: send to %s: %s\n", socket_path.c_str(), std::strerror(errno));
    return std::nullopt;
  }
  std::string in;
  char buf[8192];
  while (in.find('\n') == std::string::npos) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, conn.timeout_s * 1000) <= 0) {
      std::fprintf(stderr, "mfcd-ctl: no answer from %s within %d s\n", socket_path.c_str(), conn.timeout_s);
      return std::nullopt;
    }
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) {
      std::fprintf(stderr, "mfcd-ctl: %s closed the connection\n", socket_path.c_str());
      return std::nullopt;
    }
    in.append(buf, static_cast<std::size_t>(n));
  }
  try {
    return nlohmann::json::parse(in.substr(0, in.find('\n')));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mfcd-ctl: unreadable answer: %s\n", e.what());
    return std::nullopt;
  }
}

// What the command line asks of mfcd: the request, filled in by the subcommands' options.
struct Command {
  nlohmann::json request = nlohmann::json::object();
  bool yes = false;  // calibrate apply/rollback --yes: no question on a terminal
};

// A recipe id argument: an integer (mfcd checks its range and whether it is configured).
CLI::Option* add_recipe(CLI::App& cmd, Command& c, const std::string& help) {
  return cmd
      .add_option_function<std::string>(
          "RECIPE", [&c](const std::string& v) { c.request["recipe"] = mfcd::tools::parse_int("RECIPE", v); }, help)
      ->type_name("");
}

CLI::Option* add_pose(CLI::App& cmd, Command& c, const std::string& name, const std::string& key,
                      const std::string& help) {
  return cmd
      .add_option_function<std::string>(
          name, [&c, name, key](const std::string& v) { c.request[key] = parse_pose(v, name); }, help)
      ->type_name("x,y,z,rx,ry,rz");
}

// mfcd-ctl calibrate ACTION: each sets "action" (and "kind" for start) when selected.
void add_calibrate(CLI::App& app, Command& c) {
  CLI::App* cal = app.add_subcommand("calibrate", "the calibration workflow through the daemon (docs/operations.md)");
  cal->require_subcommand(1);
  auto action = [&c](CLI::App* sub, const std::string& name) {
    sub->preparse_callback([&c, name](std::size_t) {
      c.request["cmd"] = "calibrate";
      c.request["action"] = name;
    });
  };
  for (const char* kind : {"intrinsics", "hand-eye"}) {
    CLI::App* k = cal->add_subcommand(kind, std::string("a camera ") + kind + " session");
    k->require_subcommand(1);
    CLI::App* start = k->add_subcommand("start", std::string("start a camera ") + kind + " session (picking pauses)");
    start->preparse_callback([&c, kind](std::size_t) {
      c.request = {{"cmd", "calibrate"}, {"action", "start"}, {"kind", kind}};
    });
    if (std::string(kind) == "hand-eye")
      start
          ->add_option_function<std::string>(
              "--mode", [&c](const std::string& m) { c.request["mode"] = m; }, "eye-to-hand (default) or eye-in-hand")
          ->type_name("MODE");
  }
  CLI::App* capture = cal->add_subcommand(
      "capture", "grab the next frame set's ambient image as a view (hand-eye: with the flange pose)");
  action(capture, "capture");
  add_pose(*capture, c, "--pose", "pose", "the robot flange pose (mm, degrees)");
  capture->add_flag_callback(
      "--pose-from-plc", [&c] { c.request["pose_from_plc"] = true; },
      "the flange pose from the PLC's robot-pose block (registers 36..49)");
  add_pose(*capture, c, "--sim-plate-pose", "sim_plate_pose", "place the plate on the simulated cell");
  action(cal->add_subcommand("compute", "compute and show the figures (nothing is written)"), "compute");
  CLI::App* check = cal->add_subcommand("check", "hand-eye: predicted vs seen board in a new view");
  action(check, "check");
  add_pose(*check, c, "--pose", "pose", "the robot flange pose (mm, degrees)");
  check->add_flag_callback(
      "--pose-from-plc", [&c] { c.request["pose_from_plc"] = true; },
      "the flange pose from the PLC's robot-pose block");
  for (const char* confirmed : {"apply", "rollback"}) {
    CLI::App* sub = cal->add_subcommand(confirmed, std::string(confirmed) == "apply"
                                                       ? "write the camera file (keeps .previous) and reload"
                                                       : "restore the camera file's .previous and reload");
    action(sub, confirmed);
    sub->add_flag("-y,--yes", c.yes, "do not ask (asked on a terminal; refused without one)");
  }
  action(cal->add_subcommand("abort", "end the session without writing anything"), "abort");
  action(cal->add_subcommand("status", "show the session"), "status");
}

void add_commands(CLI::App& app, Command& c) {
  auto plain = [&](const char* name, const char* help) {
    CLI::App* sub = app.add_subcommand(name, help);
    sub->preparse_callback([&c, name](std::size_t) { c.request["cmd"] = name; });
    return sub;
  };
  plain("status", "daemon state, camera, vision backend, parts, Modbus clients");
  plain("stats", "cycle-time percentiles, overruns, detections, picks");
  plain("last", "the last cycle's result (candidates, pick, times, simulated ground truth)");
  add_recipe(*plain("trigger", "run one cycle now (not published to the PLC) and print its result"), c,
             "the recipe (default: the selected one)");
  add_recipe(*plain("snapshot", "run one cycle and save its images, depth edges, overlay and result.json"), c,
             "the recipe (default: the selected one)");
  add_recipe(*plain("part", "select the recipe for trigger/snapshot and continuous mode"), c, "the recipe")->required();
  plain("reload", "reload the configuration and templates (like SIGHUP) and report the outcome");
  add_calibrate(app, c);
  app.require_subcommand(1);
}

// calibrate apply/rollback change the camera file: without --yes, asked on a terminal after
// showing what would be written. False when the operator declined or there is no terminal.
bool confirmed(const Connection& conn, const std::string& action) {
  if (!::isatty(STDIN_FILENO)) {
    std::fprintf(stderr, "mfcd-ctl: calibrate %s changes the camera file: give --yes (no terminal to ask on)\n",
                 action.c_str());
    return false;
  }
  const auto s = round_trip(conn, {{"cmd", "calibrate"}, {"action", "status"}});
  if (!s) return false;
  const auto& session = (*s)["session"];
  if (action == "apply" && session.value("figures", "") != "")
    std::printf("%s\n", session.value("figures", "").c_str());
  std::printf("%s %s? [y/N] ", action == "apply" ? "write" : "restore the previous",
              s->value("camera_file", "the camera file").c_str());
  std::fflush(stdout);
  std::string answer;
  std::getline(std::cin, answer);
  if (answer != "y" && answer != "Y" && answer != "yes") {
    std::printf("nothing written\n");
    return false;
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"mfcd-ctl: the client of mfcd's control socket (JSON lines; docs/operations.md).", "mfcd-ctl"};
  mfcd::tools::init_app(app);
  Connection conn{std::getenv("MFCD_SOCKET") ? std::getenv("MFCD_SOCKET") : "/run/mfcd/control.sock", 60};
  app.add_option("-s,--socket", conn.socket_path, "control socket (default: $MFCD_SOCKET, else /run/mfcd/control.sock)")
      ->type_name("SOCKET");
  mfcd::tools::add_int(app, "-t,--timeout", conn.timeout_s, "seconds to wait for the answer (default 60)")
      ->type_name("SECONDS");
  Command c;
  add_commands(app, c);
  app.footer("Exit status: 0 ok, 1 refused, 2 usage or connection.");
  if (const auto code = mfcd::tools::parse(app, argc, argv)) return *code;
  const nlohmann::json& req = c.request;
  const std::string cmd = req.value("cmd", "");
  const std::string action = req.value("action", "");
  if (action == "apply" || action == "rollback") {
    if (!c.yes && !confirmed(conn, action)) return 1;
    c.request["confirm"] = true;
  }
  const auto rsp = round_trip(conn, req);
  if (!rsp) return 2;
  // Calibration figures are a table for people: printed as they are, then the whole answer.
  if (cmd == "calibrate" && rsp->contains("figures") && (*rsp)["figures"].is_string())
    std::printf("%s\n", (*rsp)["figures"].get<std::string>().c_str());
  std::printf("%s\n", rsp->dump(2).c_str());
  return rsp->value("ok", false) ? 0 : 1;
}
