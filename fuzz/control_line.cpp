// The control socket's request path, daemon/control_server.cpp, on any bytes a client may send:
// line framing, JSON parsing, dispatch through a command table, typed arguments (RequestArgs)
// and the reply written back over a real Unix socket. The bytes that once ended mfcd (an invalid
// UTF-8 byte echoed in a parse error, dump() throwing) are the kind this runs into. Besides the
// sanitizers, the harness checks that every reply the peer receives is one valid JSON object per
// line with an "ok" member.

#include "daemon/control_server.hpp"
#include "daemon/event_loop.hpp"
#include "fuzz/fuzz_support.hpp"

#include <sys/socket.h>
#include <sys/un.h>

#include <cstring>
#include <memory>
#include <string>

namespace {

using mfcd::daemon::ControlServer;
using mfcd::daemon::EventLoop;
using mfcd::daemon::RequestArgs;
using nlohmann::json;

struct Rig {
  EventLoop loop;
  ControlServer server{loop};
  mfcd::motion::UniqueFd peer;
  ControlServer::ClientId client = 1;

  Rig() {
    const auto path = mfcd::fuzz::scratch_dir() / "ctl.sock";
    // Handlers that read their arguments the ways the daemon's do.
    server.on("status", [this](ControlServer::ClientId c, const RequestArgs&) { server.reply(c, {{"ok", true}}); });
    server.on("trigger", [this](ControlServer::ClientId c, const RequestArgs& a) {
      server.reply(c, {{"ok", true}, {"recipe", a.integer("recipe", 0, 0, 65535)}});
    });
    server.on("calibrate", [this](ControlServer::ClientId c, const RequestArgs& a) {
      const std::string action = a.string("action", "");
      const bool confirm = a.boolean("confirm", false);
      const json& pose = a.request().contains("pose") ? a.request()["pose"] : json();
      if (pose.is_array() && pose.size() == 6 && !pose[0].is_number()) throw std::runtime_error("pose: not numbers");
      server.reply(c, {{"ok", !action.empty()}, {"action", action}, {"confirm", confirm}});
    });
    server.open(path);
    peer.reset(::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0));
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::strncpy(addr.sun_path, path.c_str(), sizeof addr.sun_path - 1);
    if (::connect(peer.get(), reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0)
      mfcd::fuzz::finding("cannot connect");
    loop.run_once(1000);  // accepts the peer: client 1
    if (server.clients() != 1) mfcd::fuzz::finding("the peer was not accepted");
  }
};

void check_replies(int fd) {
  std::string in;
  char buf[65536];
  for (ssize_t n; (n = ::recv(fd, buf, sizeof buf, MSG_DONTWAIT)) > 0;) in.append(buf, static_cast<std::size_t>(n));
  std::size_t start = 0;
  for (std::size_t nl; (nl = in.find('\n', start)) != std::string::npos; start = nl + 1) {
    json reply;
    try {
      reply =
          json::parse(in.begin() + static_cast<std::ptrdiff_t>(start), in.begin() + static_cast<std::ptrdiff_t>(nl));
    } catch (const std::exception&) {
      mfcd::fuzz::finding("a reply line is not valid JSON");
    }
    if (!reply.is_object() || !reply.contains("ok")) mfcd::fuzz::finding("a reply without \"ok\"");
  }
  if (start != in.size()) mfcd::fuzz::finding("a reply not ended by a newline");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static Rig* rig = new Rig;  // one server and one client for the whole run
  // Each line of the input is one request, as read_client() splits them (empty lines skipped).
  std::string_view text(reinterpret_cast<const char*>(data), size);
  while (!text.empty()) {
    const std::size_t nl = text.find('\n');
    const std::string_view line = text.substr(0, nl);
    if (!line.empty()) rig->server.handle_line(rig->client, line);
    if (nl == std::string_view::npos) break;
    text.remove_prefix(nl + 1);
  }
  check_replies(rig->peer.get());
  if (rig->server.clients() != 1) mfcd::fuzz::finding("a request closed the client");
  return 0;
}
