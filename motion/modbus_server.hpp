// Modbus/TCP server for the PLC side of the robot link (register map: register_map.hpp,
// docs/register-map.md).
//
// The server runs its own poll() loop on its own thread and serves several clients at
// once. The daemon talks to it through two lock-free handoffs:
//   - publish(RobotReport): the daemon's single result writer (e.g. the vision thread)
//     stores a snapshot in a seqlock; no lock, no allocation, no system call.
//   - next_command(): PLC commands (TRIGGER with job id / recipe / mode, RESET) come out of
//     a single-producer / single-consumer ring; command_fd() becomes readable when one is
//     queued, for the daemon's own poll loop.
// Every request is framed and checked by request_guard before libmodbus's modbus_reply()
// builds the answer.
//
// Liveness, both ways: a peer that goes silent (idle_timeout), vanishes without a FIN
// (TCP keepalive, TCP_USER_TIMEOUT) or arrives when every slot is taken (the longest-idle
// client is evicted) never locks the PLC out; and HEARTBEAT only counts while the daemon
// renews its health lease, so a hung main or vision thread shows as a frozen HEARTBEAT.
#pragma once

#include "base/unique_fd.hpp"
#include "motion/float_codec.hpp"
#include "motion/robot_report.hpp"
#include "motion/seqlock.hpp"
#include "motion/spsc_ring.hpp"

#include <atomic>
#include <chrono>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace mfcd::motion {

struct ModbusServerConfig {
  std::string bind_address = "0.0.0.0";  // IPv4 or IPv6 literal
  std::uint16_t port = 502;              // 0: let the kernel choose (tests); see port()
  WordOrder word_order = WordOrder::ABCD;
  // When every slot is taken, a new connection evicts the client that has been idle longest
  // (not one in the middle of a frame); only when all are mid-frame is it refused.
  unsigned max_clients = 8;
  // A request whose first byte has arrived must be complete within this time, or the
  // connection is closed (a PLC never pauses mid-frame; a half-open peer would hold a slot).
  std::chrono::milliseconds frame_timeout{2000};
  // A connection with no complete request for this long is closed. Default 60 s: many
  // times any PLC poll period (10 ms..1 s), and longer than a PLC that polls only around
  // its jobs pauses between them; a closed PLC connection simply reconnects.
  std::chrono::milliseconds idle_timeout{60000};
  std::vector<std::string> allow_list;  // empty: any client; else addresses / CIDR prefixes
  // The software release the server reports (registers 53..54): major << 8 | minor, and patch.
  std::uint16_t software_version = 0;
  std::uint16_t software_patch = 0;

  // Empty when valid, else a message naming the key and the reason.
  std::string validate() const;
};

struct ModbusServerStats {
  std::uint64_t connections_accepted = 0;
  std::uint64_t connections_refused = 0;  // allow-list, or max_clients with every client mid-frame
  std::uint64_t connections_dropped = 0;  // bad MBAP header, frame timeout, send failure, reset
  std::uint64_t connections_idle = 0;     // closed after idle_timeout without a request
  std::uint64_t connections_evicted = 0;  // closed to make room for a new connection
  std::uint64_t requests_answered = 0;    // answered through libmodbus
  std::uint64_t exceptions_sent = 0;
  std::uint64_t commands_queued = 0;
  unsigned clients_now = 0;
};

// TCP liveness of every accepted client socket. A peer that vanished without a FIN (power
// cycle, cable pulled) is found by keepalive probes after kKeepaliveIdle of silence plus
// kKeepaliveProbes × kKeepaliveInterval (11 s), or, when an answer stays unacknowledged,
// by TCP_USER_TIMEOUT; either way its slot frees long before idle_timeout.
inline constexpr std::chrono::seconds kKeepaliveIdle{5};
inline constexpr std::chrono::seconds kKeepaliveInterval{2};
inline constexpr int kKeepaliveProbes = 3;
inline constexpr std::chrono::milliseconds kUnacknowledgedTimeout{10000};
// TCP_NODELAY (answers go out at once) plus the keepalive settings above.
void apply_client_socket_options(int fd) noexcept;

class ModbusServer {
 public:
  // Throws std::invalid_argument when the configuration is invalid.
  explicit ModbusServer(ModbusServerConfig config);
  ~ModbusServer();
  ModbusServer(const ModbusServer&) = delete;
  ModbusServer& operator=(const ModbusServer&) = delete;

  // Binds and starts the server thread. Throws std::system_error naming the address and
  // port when the socket cannot be bound.
  void start();
  // Stops the thread and closes every connection. Call drain() first to let connected
  // PLCs read the last published report.
  void stop();
  bool running() const noexcept { return thread_.joinable(); }
  // False once the server thread has ended on its own (poll failure, exception): the robot
  // link is dead although running() is true. The daemon stops feeding its watchdog then.
  bool serving() const noexcept { return serving_.load(std::memory_order_acquire); }
  // Waits until every connected client has sent a request since the last publish() (so
  // each has read the final report), or no client is connected, or `limit` has passed.
  // Returns true unless the limit ended the wait.
  bool drain(std::chrono::milliseconds limit);
  // The bound port (the kernel's choice when the configured port was 0); valid after start().
  std::uint16_t port() const noexcept { return bound_port_; }

  // --- daemon side ---
  // Single writer. Wait-free: safe on the real-time path.
  void publish(const RobotReport& report) noexcept {
    report_.publish(report);
    published_.fetch_add(1, std::memory_order_release);
  }
  // HEARTBEAT (register 10) advances once a second only while now < `until`. The daemon
  // renews this lease from its main loop while its frame-path threads are moving, so a
  // hang in any of them freezes HEARTBEAT within the lease. Until the first lease the
  // server counts on its own (a server used without a supervisor, e.g. in tests).
  void lease_health(std::chrono::steady_clock::time_point until) noexcept {
    health_until_ns_.store(until.time_since_epoch().count(), std::memory_order_release);
  }
  // Single consumer.
  std::optional<PlcCommand> next_command() noexcept;
  // Readable (eventfd) while commands are queued; -1 before start().
  int command_fd() const noexcept { return command_event_fd_.get(); }
  // The robot pose block as the PLC last wrote it (seqlock: wait-free for the server thread).
  RobotPoseReading robot_pose() const noexcept { return robot_pose_.read(); }

  ModbusServerStats stats() const noexcept;

 private:
  struct Impl;
  void run() noexcept;

  ModbusServerConfig config_;
  std::unique_ptr<Impl> impl_;
  SeqlockSnapshot<RobotReport> report_;
  SeqlockSnapshot<RobotPoseReading> robot_pose_;
  SpscRing<PlcCommand, 16> commands_;
  UniqueFd command_event_fd_;
  UniqueFd stop_event_fd_;
  UniqueFd listen_fd_;
  std::uint16_t bound_port_ = 0;
  std::thread thread_;
  std::atomic<bool> serving_{false};
  std::atomic<std::uint64_t> published_{0};       // publish() calls so far
  std::atomic<std::uint64_t> least_seen_{~0ull};  // min over clients of the publish count they read
  std::atomic<std::int64_t> health_until_ns_{std::numeric_limits<std::int64_t>::max()};

  std::atomic<std::uint64_t> accepted_{0}, refused_{0}, dropped_{0}, idle_{0}, evicted_{0}, answered_{0},
      exceptions_{0}, queued_{0};
  std::atomic<unsigned> clients_now_{0};
};

}  // namespace mfcd::motion
