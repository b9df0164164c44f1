#include "daemon/control_server.hpp"

#include <fcntl.h>
#include <grp.h>
#include <pwd.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <optional>
#include <stdexcept>
#include <system_error>

#include "daemon/log.hpp"

namespace mfcd::daemon {

using nlohmann::json;
namespace fs = std::filesystem;

long long RequestArgs::integer(const char* key, long long fallback, long long lo, long long hi) const {
  if (!j_.contains(key)) return fallback;
  const json& v = j_[key];
  if (!v.is_number_integer() || v.get<long long>() < lo || v.get<long long>() > hi)
    throw std::invalid_argument(std::string(key) + " must be an integer " + std::to_string(lo) + ".." +
                                std::to_string(hi));
  return v.get<long long>();
}

std::string RequestArgs::string(const char* key, const std::string& fallback) const {
  if (!j_.contains(key)) return fallback;
  if (!j_[key].is_string()) throw std::invalid_argument(std::string(key) + " must be a string");
  return j_[key].get<std::string>();
}

bool RequestArgs::boolean(const char* key, bool fallback) const {
  if (!j_.contains(key)) return fallback;
  if (!j_[key].is_boolean()) throw std::invalid_argument(std::string(key) + " must be true or false");
  return j_[key].get<bool>();
}

namespace {

bool peer_allowed(int fd, uid_t& uid_out) {
  ucred cred{};
  socklen_t len = sizeof cred;
  if (::getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &cred, &len) != 0) return false;
  uid_out = cred.uid;
  if (cred.uid == 0 || cred.uid == ::geteuid() || cred.gid == ::getegid()) return true;
  // Members of the daemon's group (supplementary groups of the peer's user).
  passwd pw{}, *found = nullptr;
  std::vector<char> buf(16384);
  if (getpwuid_r(cred.uid, &pw, buf.data(), buf.size(), &found) != 0 || !found) return false;
  int n = 64;
  std::vector<gid_t> groups(static_cast<std::size_t>(n));
  if (getgrouplist(pw.pw_name, pw.pw_gid, groups.data(), &n) < 0) return false;
  for (int i = 0; i < n; ++i)
    if (groups[static_cast<std::size_t>(i)] == ::getegid()) return true;
  return false;
}

std::string line_of(const json& j) { return j.dump(-1, ' ', false, json::error_handler_t::replace) + "\n"; }

// Sends what the socket takes now without waiting: the bytes sent, or nullopt when the socket
// failed (the peer is gone).
std::optional<std::size_t> send_some(int fd, std::string_view bytes) {
  std::size_t sent = 0;
  while (sent < bytes.size()) {
    const ssize_t n = ::send(fd, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL | MSG_DONTWAIT);
    if (n > 0) {
      sent += static_cast<std::size_t>(n);
    } else if (n < 0 && errno == EINTR) {
      continue;
    } else if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      break;
    } else {
      return std::nullopt;
    }
  }
  return sent;
}

}  // namespace

void ControlServer::open(const fs::path& path) {
  std::error_code ec;
  fs::create_directories(path.parent_path(), ec);
  UniqueFd fd(::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0));
  if (!fd) throw std::system_error(errno, std::generic_category(), "control socket");
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (path.native().size() >= sizeof addr.sun_path)
    throw std::runtime_error("control socket " + path.string() + ": path longer than " +
                             std::to_string(sizeof addr.sun_path - 1) + " bytes");
  std::strncpy(addr.sun_path, path.c_str(), sizeof addr.sun_path - 1);
  // A leftover socket file from a crash is removed; a live one means another mfcd is running.
  if (fs::exists(path)) {
    UniqueFd probe(::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0));
    if (probe && ::connect(probe.get(), reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0)
      throw std::runtime_error("control socket " + path.string() + ": another mfcd is listening there");
    ::unlink(path.c_str());
  }
  if (::bind(fd.get(), reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0)
    throw std::runtime_error("control socket " + path.string() + ": bind: " + std::strerror(errno) +
                             "; check daemon.control_socket and that its directory is writable");
  ::chmod(path.c_str(), 0660);
  if (::listen(fd.get(), 8) != 0) throw std::system_error(errno, std::generic_category(), "listen " + path.string());
  listener_ = std::move(fd);
  path_ = path;
  reserve_.reset(::open("/dev/null", O_RDONLY | O_CLOEXEC));
  loop_.add(listener_.get(), [this] { accept_clients(); });
  logf(LogLevel::Info, "control socket %s", path.c_str());
}

void ControlServer::close() {
  // What is queued gets one last try (a "mfcd is stopping" reply, say), without waiting.
  for (const Client& c : clients_)
    if (!c.hung_up && !c.out.empty()) send_some(c.fd.get(), c.out);
  while (!clients_.empty()) drop(clients_.back().id);
  if (listener_) {
    loop_.remove(listener_.get());
    listener_.reset();
    ::unlink(path_.c_str());
  }
  reserve_.reset();
}

void ControlServer::refuse(UniqueFd fd, const char* why) {
  ++refused_;
  send_some(fd.get(), line_of({{"ok", false}, {"error", why}}));  // a new socket takes one short line
}

void ControlServer::accept_clients() {
  for (;;) {
    UniqueFd fd(::accept4(listener_.get(), nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK));
    if (!fd) {
      if (errno != EMFILE && errno != ENFILE) return;
      // Out of descriptors: the pending connection would keep the listener readable and the
      // loop spinning. Give up the spare descriptor, take the connection and refuse it.
      logf(LogLevel::Warning, "control socket: out of file descriptors (%s); refusing a client", std::strerror(errno));
      reserve_.reset();
      UniqueFd pending(::accept4(listener_.get(), nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK));
      if (pending) refuse(std::move(pending), "mfcd is out of file descriptors; try again later");
      reserve_.reset(::open("/dev/null", O_RDONLY | O_CLOEXEC));
      return;
    }
    uid_t uid = 0;
    if (!peer_allowed(fd.get(), uid)) {
      // Logged before the answer: when the client sees the refusal, the record of it exists.
      logf(LogLevel::Notice, "control socket: refused a client with uid %u", static_cast<unsigned>(uid));
      refuse(std::move(fd), "permission denied: only root, the daemon's user or members of its group may control mfcd");
      continue;
    }
    if (clients_.size() >= kMaxClients) {
      logf(LogLevel::Warning, "control socket: refused a client: %zu clients connected", clients_.size());
      refuse(std::move(fd), "too many control clients connected; try again later");
      continue;
    }
    const ClientId id = next_id_++;
    loop_.add(fd.get(), [this, id] { read_client(id); });
    clients_.push_back({std::move(fd), {}, {}, uid, id, false});
  }
}

ControlServer::Client* ControlServer::find(ClientId id) {
  const auto it = std::find_if(clients_.begin(), clients_.end(), [id](const Client& c) { return c.id == id; });
  return it == clients_.end() ? nullptr : &*it;
}

const ControlServer::Client* ControlServer::find(ClientId id) const {
  const auto it = std::find_if(clients_.begin(), clients_.end(), [id](const Client& c) { return c.id == id; });
  return it == clients_.end() ? nullptr : &*it;
}

void ControlServer::drop(ClientId id) {
  const auto it = std::find_if(clients_.begin(), clients_.end(), [id](const Client& c) { return c.id == id; });
  if (it == clients_.end()) return;
  loop_.remove(it->fd.get());
  clients_.erase(it);
  if (on_disconnect_) on_disconnect_(id);
}

bool ControlServer::reply(ClientId client, const json& j) {
  Client* c = find(client);
  if (!c || c->hung_up) return false;
  const std::string line = line_of(j);
  if (!c->out.empty()) {  // behind what is queued, to keep the order
    if (c->out.size() + line.size() > kMaxQueued) {
      hang_up(*c, "it leaves its replies unread");
      return false;
    }
    c->out += line;
    return true;
  }
  const std::optional<std::size_t> sent = send_some(c->fd.get(), line);
  if (!sent) {
    hang_up(*c, "its socket failed");
    return false;
  }
  if (*sent < line.size()) {
    c->out.assign(line, *sent);
    loop_.on_writable(c->fd.get(), [this, client] { write_client(client); });
  }
  return true;
}

std::size_t ControlServer::queued(ClientId client) const {
  const Client* c = find(client);
  return c ? c->out.size() : 0;
}

void ControlServer::write_client(ClientId id) {
  Client* c = find(id);
  if (!c || c->hung_up) return;
  const std::optional<std::size_t> sent = send_some(c->fd.get(), c->out);
  if (!sent) {
    hang_up(*c, "its socket failed");
    return;
  }
  c->out.erase(0, *sent);
  if (c->out.empty()) loop_.on_writable(c->fd.get(), {});
}

// Shuts the socket both ways: the peer sees the end, and the socket reads as ended, so the
// loop's next round calls read_client, which drops the client at a point where that is safe.
void ControlServer::hang_up(Client& c, const char* why) {
  logf(LogLevel::Warning, "control socket: dropping client %llu: %s (%zu bytes of replies unsent)",
       static_cast<unsigned long long>(c.id), why, c.out.size());
  c.hung_up = true;
  c.out.clear();
  c.out.shrink_to_fit();
  ::shutdown(c.fd.get(), SHUT_RDWR);
  loop_.on_writable(c.fd.get(), {});
}

void ControlServer::read_client(ClientId id) {
  char buf[4096];
  for (;;) {
    Client* c = find(id);
    if (!c) return;
    if (c->hung_up) {
      drop(id);
      return;
    }
    const ssize_t n = ::recv(c->fd.get(), buf, sizeof buf, 0);
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) break;
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      drop(id);
      return;
    }
    c->in.append(buf, static_cast<std::size_t>(n));
    if (c->in.size() > kMaxLine && c->in.find('\n') == std::string::npos) {
      reply(id, {{"ok", false}, {"error", "request line too long (more than " + std::to_string(kMaxLine) + " bytes)"}});
      drop(id);
      return;
    }
  }
  // Each line is taken out of the buffer before it runs: a handler may close this client.
  for (;;) {
    Client* c = find(id);
    if (!c) return;
    if (c->hung_up) {  // a reply dropped it: its other requests are not run
      drop(id);
      return;
    }
    const std::size_t nl = c->in.find('\n');
    if (nl == std::string::npos) return;
    const std::string line = c->in.substr(0, nl);
    c->in.erase(0, nl + 1);
    if (!line.empty()) handle_line(id, line);
  }
}

void ControlServer::handle_line(ClientId client, std::string_view line) {
  json req;
  try {
    req = json::parse(line);
  } catch (const std::exception& e) {
    reply(client, {{"ok", false}, {"error", std::string("bad request (one JSON object per line): ") + e.what()}});
    return;
  }
  const std::string cmd =
      req.is_object() && req.contains("cmd") && req["cmd"].is_string() ? req["cmd"].get<std::string>() : "";
  const auto it = commands_.find(cmd);
  if (it == commands_.end()) {
    std::string known;
    for (const auto& [name, handler] : commands_) known += (known.empty() ? "" : ", ") + name;
    reply(client, {{"ok", false}, {"error", "unknown command '" + cmd + "' (" + known + ")"}});
    return;
  }
  // The barrier: whatever a handler throws becomes this request's error answer.
  try {
    it->second(client, RequestArgs(req));
  } catch (const std::invalid_argument& e) {
    reply(client, {{"ok", false}, {"error", cmd + ": " + e.what()}});
  } catch (const std::exception& e) {
    logf(LogLevel::Warning, "control socket: request '%s' failed: %s", cmd.c_str(), e.what());
    reply(client, {{"ok", false}, {"error", std::string("request failed: ") + e.what()}});
  }
}

}  // namespace mfcd::daemon
