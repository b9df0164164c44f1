#pragma once
// The control socket (mfcd-ctl): a Unix stream socket, mode 0660, for root, the daemon's user and
// members of its group (SO_PEERCRED); one JSON object per line each way. Requests are dispatched
// through a command table the daemon fills; a request that throws is answered with its error and
// never reaches the main loop. Replies never block the loop: what the socket does not take is
// queued and sent when the client's socket is writable. Bounded: at most kMaxClients at once,
// lines up to kMaxLine bytes, kMaxQueued bytes of replies left unread (a client that leaves more
// is dropped), and descriptor exhaustion (EMFILE) refuses the newcomer instead of spinning on
// the listener.
#include <sys/types.h>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "base/unique_fd.hpp"
#include "daemon/event_loop.hpp"

namespace mfcd::daemon {

// Typed access to a request's arguments: each getter throws std::invalid_argument naming the key
// and what it must be, which the server's barrier turns into {"ok": false, "error": ...}.
class RequestArgs {
 public:
  explicit RequestArgs(const nlohmann::json& request) : j_(request) {}
  bool has(const char* key) const { return j_.contains(key); }
  long long integer(const char* key, long long fallback, long long lo, long long hi) const;
  std::string string(const char* key, const std::string& fallback) const;
  bool boolean(const char* key, bool fallback) const;
  const nlohmann::json& request() const { return j_; }

 private:
  const nlohmann::json& j_;
};

class ControlServer {
 public:
  using ClientId = std::uint64_t;  // stable for a connection's life; never reused
  using Handler = std::function<void(ClientId, const RequestArgs&)>;
  static constexpr std::size_t kMaxClients = 16;
  static constexpr std::size_t kMaxLine = 65536;
  static constexpr std::size_t kMaxQueued = std::size_t{1} << 20;  // bytes of unread replies per client

  explicit ControlServer(EventLoop& loop) : loop_(loop) {}
  ~ControlServer() { close(); }
  ControlServer(const ControlServer&) = delete;
  ControlServer& operator=(const ControlServer&) = delete;

  // Binds `path` (a leftover socket file from a crash is replaced; a live one means another mfcd)
  // and registers with the event loop. Throws std::runtime_error naming the path.
  void open(const std::filesystem::path& path);
  // Closes every client and the listener and removes the socket file.
  void close();

  // The command table: {"cmd": name, ...} calls handler(client, args).
  void on(std::string name, Handler handler) { commands_[std::move(name)] = std::move(handler); }
  // Called when a client disconnects (or is dropped), so what waits for it can be forgotten.
  void on_disconnect(std::function<void(ClientId)> callback) { on_disconnect_ = std::move(callback); }

  // Sends one JSON line, or queues what the socket does not take; invalid UTF-8 in strings is
  // replaced (U+FFFD). False when the client is gone or is being dropped: its socket failed, or
  // this reply would leave more than kMaxQueued bytes unread. A dropped client is shut down here
  // and removed (with on_disconnect) by the loop's next round, never inside this call: callers
  // may be iterating what on_disconnect changes.
  bool reply(ClientId client, const nlohmann::json& j);
  // Bytes of replies queued for the client (0 when all were sent or it is gone).
  std::size_t queued(ClientId client) const;
  // Parses and dispatches one request line as if `client` had sent it (what read() does).
  void handle_line(ClientId client, std::string_view line);
  std::size_t clients() const { return clients_.size(); }
  std::uint64_t refused() const { return refused_; }

 private:
  struct Client {
    UniqueFd fd;
    std::string in;
    std::string out;  // reply bytes the socket has not taken yet, in order
    uid_t uid = 0;
    ClientId id = 0;
    bool hung_up = false;  // shut down; the next loop round drops it
  };
  void accept_clients();
  void read_client(ClientId id);
  void write_client(ClientId id);
  void hang_up(Client& c, const char* why);
  void drop(ClientId id);
  Client* find(ClientId id);
  const Client* find(ClientId id) const;
  void refuse(UniqueFd fd, const char* why);

  EventLoop& loop_;
  std::filesystem::path path_;
  UniqueFd listener_;
  UniqueFd reserve_;  // a spare descriptor, given up to accept-and-refuse at EMFILE
  std::vector<Client> clients_;
  std::map<std::string, Handler, std::less<>> commands_;
  std::function<void(ClientId)> on_disconnect_;
  ClientId next_id_ = 1;
  std::uint64_t refused_ = 0;
};

}  // namespace mfcd::daemon
