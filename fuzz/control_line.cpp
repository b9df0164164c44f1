// The control socket's request path, daemon/control_server.cpp, on any bytes a client may send:
// line framing, JSON parsing, dispatch through a command table, typed arguments (RequestArgs)
// and the reply written back over a real Unix socket. The bytes that once ended mfcd (an invalid
// UTF-8 byte echoed in a parse error, dump() throwing) are the kind this runs into. The peer reads
// its replies as a client does, between requests; the server's loop runs between them, so what
// the socket did not take is sent from its queue. Besides the sanitizers, the harness checks that
// every request gets exactly one reply, each one valid JSON object per line with an "ok" member,
// and that no request closes the client.

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
  mfcd::UniqueFd peer;
  ControlServer::ClientId client = 1;
  std::string in;           // reply bytes received, not yet a whole line
  std::size_t replies = 0;  // whole reply lines received

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

// Reads what has arrived; checks and counts the whole lines, keeps a partial one for later.
void take_replies(Rig& rig) {
  char buf[65536];
  for (ssize_t n; (n = ::recv(rig.peer.get(), buf, sizeof buf, MSG_DONTWAIT)) > 0;)
    rig.in.append(buf, static_cast<std::size_t>(n));
  std::size_t start = 0;
  for (std::size_t nl; (nl = rig.in.find('\n', start)) != std::string::npos; start = nl + 1) {
    json reply;
    try {
      reply = json::parse(rig.in.begin() + static_cast<std::ptrdiff_t>(start),
                          rig.in.begin() + static_cast<std::ptrdiff_t>(nl));
    } catch (const std::exception&) {
      mfcd::fuzz::finding("a reply line is not valid JSON");
    }
    if (!reply.is_object() || !reply.contains("ok")) mfcd::fuzz::finding("a reply without \"ok\"");
    ++rig.replies;
  }
  rig.in.erase(0, start);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static Rig* rig = new Rig;  // one server and one client for the whole run
  // Each line of the input is one request, as read_client() splits them (empty lines skipped).
  std::string_view text(reinterpret_cast<const char*>(data), size);
  std::size_t requests = 0;
  rig->replies = 0;
  while (!text.empty()) {
    const std::size_t nl = text.find('\n');
    const std::string_view line = text.substr(0, nl);
    if (!line.empty()) {
      rig->server.handle_line(rig->client, line);
      ++requests;
      rig->loop.run_once(0);
      take_replies(*rig);
    }
    if (nl == std::string_view::npos) break;
    text.remove_prefix(nl + 1);
  }
  // The rest of the queue goes out as the peer reads.
  for (int round = 0; round < 1000 && (rig->server.queued(rig->client) > 0 || rig->replies < requests); ++round) {
    rig->loop.run_once(10);
    take_replies(*rig);
  }
  if (rig->server.clients() != 1) mfcd::fuzz::finding("a request closed the client");
  if (!rig->in.empty()) mfcd::fuzz::finding("a reply not ended by a newline");
  if (rig->replies != requests) mfcd::fuzz::finding("a request without exactly one reply");
  return 0;
}
