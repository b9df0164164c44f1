#include "motion/modbus_server.hpp"

#include "motion/modbus_server_impl.hpp"
#include "motion/register_map.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <syslog.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <system_error>

namespace mfcd::motion {

using Clock = std::chrono::steady_clock;

std::string ModbusServerConfig::validate() const {
  in6_addr scratch;
  if (inet_pton(AF_INET, bind_address.c_str(), &scratch) != 1 &&
      inet_pton(AF_INET6, bind_address.c_str(), &scratch) != 1)
    return "modbus bind_address '" + bind_address + "': not an IPv4 or IPv6 address";
  if (max_clients < 1 || max_clients > 64)
    return "modbus max_clients " + std::to_string(max_clients) + ": must be 1..64";
  if (frame_timeout.count() < 10 || frame_timeout.count() > 60000)
    return "modbus frame_timeout_ms " + std::to_string(frame_timeout.count()) + ": must be 10..60000";
  if (idle_timeout.count() < 100 || idle_timeout.count() > 3600000)
    return "modbus idle_timeout_ms " + std::to_string(idle_timeout.count()) + ": must be 100..3600000";
  try {
    IpAllowList check(allow_list);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return {};
}

void apply_client_socket_options(int fd) noexcept {
  const int one = 1;
  const int idle_s = kKeepaliveIdle.count(), interval_s = kKeepaliveInterval.count(), probes = kKeepaliveProbes;
  const unsigned user_timeout_ms = static_cast<unsigned>(kUnacknowledgedTimeout.count());
  ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));
  ::setsockopt(fd, SOL_SOCKET, SO_KEEPALIVE, &one, sizeof(one));
  ::setsockopt(fd, IPPROTO_TCP, TCP_KEEPIDLE, &idle_s, sizeof(idle_s));
  ::setsockopt(fd, IPPROTO_TCP, TCP_KEEPINTVL, &interval_s, sizeof(interval_s));
  ::setsockopt(fd, IPPROTO_TCP, TCP_KEEPCNT, &probes, sizeof(probes));
  ::setsockopt(fd, IPPROTO_TCP, TCP_USER_TIMEOUT, &user_timeout_ms, sizeof(user_timeout_ms));
}

ModbusServer::Impl::Impl(ModbusServer& s)
    : server(s), config(s.config_), allow(s.config_.allow_list), clients(s.config_.max_clients) {
  ctx = modbus_new_tcp("127.0.0.1", 502);  // only used to build replies; never connects
  map = modbus_mapping_new(0, 0, reg::kBlockSize, reg::kBlockSize);
  if (!ctx || !map) {
    modbus_mapping_free(map);
    modbus_free(ctx);
    throw std::runtime_error("modbus: cannot allocate libmodbus context");
  }
}

ModbusServer::Impl::~Impl() {
  modbus_mapping_free(map);
  modbus_free(ctx);
}

ModbusServer::ModbusServer(ModbusServerConfig config) : config_(std::move(config)) {
  if (std::string error = config_.validate(); !error.empty()) throw std::invalid_argument(error);
  impl_ = std::make_unique<Impl>(*this);
}

ModbusServer::~ModbusServer() { stop(); }

void ModbusServer::start() {
  if (running()) return;
  const std::string where = config_.bind_address + ":" + std::to_string(config_.port);
  const auto fail = [&](const char* what) {
    const int err = errno;
    listen_fd_.reset();
    return std::system_error(err, std::generic_category(), std::string("modbus: cannot ") + what + " " + where);
  };

  sockaddr_storage addr{};
  socklen_t addr_len = 0;
  auto* in4 = reinterpret_cast<sockaddr_in*>(&addr);
  auto* in6 = reinterpret_cast<sockaddr_in6*>(&addr);
  if (inet_pton(AF_INET, config_.bind_address.c_str(), &in4->sin_addr) == 1) {
    in4->sin_family = AF_INET;
    in4->sin_port = htons(config_.port);
    addr_len = sizeof(sockaddr_in);
  } else {
    inet_pton(AF_INET6, config_.bind_address.c_str(), &in6->sin6_addr);
    in6->sin6_family = AF_INET6;
    in6->sin6_port = htons(config_.port);
    addr_len = sizeof(sockaddr_in6);
  }

  listen_fd_.reset(::socket(addr.ss_family, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0));
  if (!listen_fd_) throw fail("open socket for");
  const int one = 1;
  ::setsockopt(listen_fd_.get(), SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
  if (::bind(listen_fd_.get(), reinterpret_cast<sockaddr*>(&addr), addr_len) < 0) throw fail("bind");
  if (::listen(listen_fd_.get(), 16) < 0) throw fail("listen on");
  sockaddr_storage bound{};
  socklen_t bound_len = sizeof(bound);
  ::getsockname(listen_fd_.get(), reinterpret_cast<sockaddr*>(&bound), &bound_len);
  bound_port_ = ntohs(bound.ss_family == AF_INET ? reinterpret_cast<sockaddr_in*>(&bound)->sin_port
                                                 : reinterpret_cast<sockaddr_in6*>(&bound)->sin6_port);

  stop_event_fd_.reset(::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK));
  if (!command_event_fd_) command_event_fd_.reset(::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK));
  if (!stop_event_fd_ || !command_event_fd_) throw fail("create eventfd for");

  impl_->fds.reserve(2 + impl_->clients.size());
  impl_->next_beat = Clock::now() + std::chrono::seconds(1);
  syslog(LOG_INFO, "modbus: listening on %s:%u, word order %s, %u clients max, idle timeout %lld ms",
         config_.bind_address.c_str(), bound_port_, std::string(to_string(config_.word_order)).c_str(),
         config_.max_clients, static_cast<long long>(config_.idle_timeout.count()));
  serving_.store(true, std::memory_order_release);
  thread_ = std::thread([this] { run(); });
}

void ModbusServer::stop() {
  if (!thread_.joinable()) return;
  const std::uint64_t one = 1;
  [[maybe_unused]] ssize_t n = ::write(stop_event_fd_.get(), &one, sizeof(one));
  thread_.join();
  for (Impl::Client& c : impl_->clients)
    if (c.fd) impl_->close_client(c, Impl::CloseReason::PeerClosed);
  listen_fd_.reset();
  stop_event_fd_.reset();
}

bool ModbusServer::drain(std::chrono::milliseconds limit) {
  const auto end = Clock::now() + limit;
  for (;;) {
    if (!serving() || least_seen_.load(std::memory_order_acquire) >= published_.load(std::memory_order_acquire))
      return true;
    if (Clock::now() >= end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

std::optional<PlcCommand> ModbusServer::next_command() noexcept {
  // Drain the eventfd before popping: a command pushed after the drain re-arms it, so a
  // queued command never goes without a wake-up (at worst one spurious wake-up).
  if (command_event_fd_) {
    std::uint64_t count;
    [[maybe_unused]] ssize_t n = ::read(command_event_fd_.get(), &count, sizeof(count));
  }
  return commands_.pop();
}

ModbusServerStats ModbusServer::stats() const noexcept {
  ModbusServerStats s;
  s.connections_accepted = accepted_.load();
  s.connections_refused = refused_.load();
  s.connections_dropped = dropped_.load();
  s.connections_idle = idle_.load();
  s.connections_evicted = evicted_.load();
  s.requests_answered = answered_.load();
  s.exceptions_sent = exceptions_.load();
  s.commands_queued = queued_.load();
  s.clients_now = clients_now_.load();
  return s;
}

void ModbusServer::run() noexcept {
  try {
    while (impl_->serve_once()) {
    }
  } catch (const std::exception& e) {
    syslog(LOG_ERR, "modbus: server thread failed: %s", e.what());
  } catch (...) {
    syslog(LOG_ERR, "modbus: server thread failed (unknown exception)");
  }
  serving_.store(false, std::memory_order_release);
}

// --- connections ---

void ModbusServer::Impl::close_client(Client& c, CloseReason why) {
  // Count before closing, so whoever sees the close also sees the count.
  server.clients_now_.fetch_sub(1);
  switch (why) {
    case CloseReason::PeerClosed:
      break;
    case CloseReason::Dropped:
      server.dropped_.fetch_add(1);
      break;
    case CloseReason::Idle:
      server.idle_.fetch_add(1);
      break;
    case CloseReason::Evicted:
      server.evicted_.fetch_add(1);
      break;
  }
  c.fd.reset();
  c.have = 0;
  c.need = kMbapHeaderSize;
  update_least_seen();
}

void ModbusServer::Impl::update_least_seen() noexcept {
  std::uint64_t least = ~0ull;
  for (const Client& c : clients)
    if (c.fd) least = std::min(least, c.seen);
  server.least_seen_.store(least, std::memory_order_release);
}

void ModbusServer::Impl::advance_heartbeat(Clock::time_point now) {
  const std::int64_t lease = server.health_until_ns_.load(std::memory_order_acquire);
  while (now >= next_beat) {
    if (next_beat.time_since_epoch().count() < lease) ++heartbeat;
    next_beat += std::chrono::seconds(1);
  }
}

Clock::time_point ModbusServer::Impl::expire_clients(Clock::time_point now, Clock::time_point deadline) {
  for (Client& c : clients) {
    if (!c.fd) continue;
    if (c.have != 0) {
      if (now - c.frame_started > config.frame_timeout) {
        close_client(c, CloseReason::Dropped);
        continue;
      }
      deadline = std::min(deadline, c.frame_started + config.frame_timeout);
    } else {
      if (now - c.last_request > config.idle_timeout) {
        syslog(LOG_NOTICE, "modbus: closed a client idle for %lld ms",
               static_cast<long long>(config.idle_timeout.count()));
        close_client(c, CloseReason::Idle);
        continue;
      }
      deadline = std::min(deadline, c.last_request + config.idle_timeout);
    }
  }
  return deadline;
}

void ModbusServer::Impl::read_client(Client& c) {
  while (c.fd) {
    const ssize_t n = ::recv(c.fd.get(), c.buf + c.have, c.need - c.have, MSG_DONTWAIT);
    if (n == 0) {
      close_client(c, c.have != 0 ? CloseReason::Dropped : CloseReason::PeerClosed);
      return;
    }
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno != EAGAIN && errno != EWOULDBLOCK)
        close_client(c, CloseReason::Dropped);  // reset, keepalive or user timeout
      return;
    }
    if (c.have == 0) c.frame_started = Clock::now();
    c.have += static_cast<std::size_t>(n);
    if (c.have < c.need) continue;
    if (c.need == kMbapHeaderSize) {
      const std::size_t size = mbap_frame_size(std::span<const std::uint8_t, kMbapHeaderSize>(c.buf, kMbapHeaderSize));
      if (size == 0) {
        // No trustworthy frame boundary after a bad header: drop the connection.
        close_client(c, CloseReason::Dropped);
        return;
      }
      c.need = size;
      if (c.have < c.need) continue;
    }
    const std::size_t size = c.have;
    c.have = 0;
    c.need = kMbapHeaderSize;
    c.last_request = Clock::now();
    handle_frame(c, size);
    update_least_seen();
  }
}

// A free slot, or the slot of the longest-idle client (closed to make room); nullptr when
// every client is in the middle of a frame.
ModbusServer::Impl::Client* ModbusServer::Impl::free_slot(Clock::time_point now) {
  Client* idlest = nullptr;
  for (Client& c : clients) {
    if (!c.fd) return &c;
    if (c.have == 0 && (!idlest || c.last_request < idlest->last_request)) idlest = &c;
  }
  if (idlest) {
    syslog(LOG_NOTICE, "modbus: max_clients %u reached: closed the client idle longest (%lld ms)", config.max_clients,
           static_cast<long long>(
               std::chrono::duration_cast<std::chrono::milliseconds>(now - idlest->last_request).count()));
    close_client(*idlest, CloseReason::Evicted);
  }
  return idlest;
}

void ModbusServer::Impl::accept_clients() {
  for (;;) {
    sockaddr_storage peer{};
    socklen_t peer_len = sizeof(peer);
    UniqueFd fd(::accept4(server.listen_fd_.get(), reinterpret_cast<sockaddr*>(&peer), &peer_len,
                          SOCK_NONBLOCK | SOCK_CLOEXEC));
    if (!fd) {
      if (errno == EMFILE || errno == ENFILE)
        syslog(LOG_ERR, "modbus: cannot accept a client: %s", std::strerror(errno));
      return;
    }
    if (!allow.allows(reinterpret_cast<sockaddr*>(&peer))) {
      char text[INET6_ADDRSTRLEN] = "?";
      const void* a = peer.ss_family == AF_INET
                          ? static_cast<const void*>(&reinterpret_cast<sockaddr_in*>(&peer)->sin_addr)
                          : static_cast<const void*>(&reinterpret_cast<sockaddr_in6*>(&peer)->sin6_addr);
      inet_ntop(peer.ss_family, a, text, sizeof(text));
      syslog(LOG_WARNING, "modbus: refused client %s: not in allow_list", text);
      server.refused_.fetch_add(1);
      continue;
    }
    const Clock::time_point now = Clock::now();
    Client* slot = free_slot(now);
    if (!slot) {
      // Every client is mid-frame; some may have gone already (a PLC that dropped mid-request
      // and reconnects at once): reap the closes not yet read before refusing the newcomer.
      for (Client& c : clients)
        if (c.fd) read_client(c);
      slot = free_slot(now);
    }
    if (!slot) {
      syslog(LOG_WARNING, "modbus: refused client: max_clients %u reached, all mid-frame", config.max_clients);
      server.refused_.fetch_add(1);
      continue;
    }
    apply_client_socket_options(fd.get());
    slot->fd = std::move(fd);
    slot->have = 0;
    slot->need = kMbapHeaderSize;
    slot->last_request = now;
    slot->seen = 0;
    server.accepted_.fetch_add(1);
    server.clients_now_.fetch_add(1);
    update_least_seen();
  }
}

bool ModbusServer::Impl::serve_once() {
  const Clock::time_point now = Clock::now();
  advance_heartbeat(now);
  const Clock::time_point deadline = expire_clients(now, next_beat);

  fds.clear();
  fds.push_back({server.stop_event_fd_.get(), POLLIN, 0});
  fds.push_back({server.listen_fd_.get(), POLLIN, 0});
  for (const Client& c : clients)
    if (c.fd) fds.push_back({c.fd.get(), POLLIN, 0});
  const auto wait = std::chrono::ceil<std::chrono::milliseconds>(deadline - now).count();
  const int ready = ::poll(fds.data(), fds.size(), static_cast<int>(std::clamp<long>(wait, 1, 1000)));
  if (ready < 0 && errno != EINTR) {
    syslog(LOG_ERR, "modbus: poll failed: %s; the robot link is down", std::strerror(errno));
    return false;
  }
  if (ready <= 0) return true;
  if (fds[0].revents) return false;
  if (fds[1].revents & POLLIN) accept_clients();
  for (std::size_t i = 2; i < fds.size(); ++i) {
    if (!fds[i].revents) continue;
    auto c = std::find_if(clients.begin(), clients.end(), [&](const Client& cl) { return cl.fd.get() == fds[i].fd; });
    if (c != clients.end()) read_client(*c);
  }
  return true;
}

}  // namespace mfcd::motion
