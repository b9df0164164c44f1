// Modbus/TCP server for the PLC side of the robot link (register map: register_map.h,
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
#pragma once

#include "motion/float_codec.h"
#include "motion/robot_report.h"
#include "motion/seqlock.h"
#include "motion/spsc_queue.h"

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace mfcd::motion {

struct ModbusServerConfig {
	std::string bind_address = "0.0.0.0"; // IPv4 or IPv6 literal
	std::uint16_t port = 502;             // 0: let the kernel choose (tests); see port()
	WordOrder word_order = WordOrder::ABCD;
	unsigned max_clients = 8;             // further connections are closed at once
	// A request whose first byte has arrived must be complete within this time, or the
	// connection is closed (a PLC never pauses mid-frame; a half-open peer would hold a slot).
	std::chrono::milliseconds frame_timeout{2000};
	std::vector<std::string> allow_list;  // empty: any client; else addresses / CIDR prefixes

	// Empty when valid, else a message naming the key and the reason.
	std::string validate() const;
};

struct ModbusServerStats {
	std::uint64_t connections_accepted = 0;
	std::uint64_t connections_refused = 0; // allow-list or max_clients
	std::uint64_t connections_dropped = 0; // bad MBAP header, frame timeout, send failure
	std::uint64_t requests_answered = 0;   // answered through libmodbus
	std::uint64_t exceptions_sent = 0;
	std::uint64_t commands_queued = 0;
	unsigned clients_now = 0;
};

class ModbusServer
{
public:
	// Throws std::invalid_argument when the configuration is invalid.
	explicit ModbusServer(ModbusServerConfig config);
	~ModbusServer();
	ModbusServer(const ModbusServer &) = delete;
	ModbusServer &operator=(const ModbusServer &) = delete;

	// Binds and starts the server thread. Throws std::system_error naming the address and
	// port when the socket cannot be bound.
	void start();
	void stop();
	bool running() const noexcept { return thread_.joinable(); }
	// The bound port (the kernel's choice when the configured port was 0); valid after start().
	std::uint16_t port() const noexcept { return bound_port_; }

	// --- daemon side ---
	// Single writer. Wait-free: safe on the real-time path.
	void publish(const RobotReport &report) noexcept { report_.publish(report); }
	// Single consumer.
	std::optional<PlcCommand> next_command() noexcept;
	// Readable (eventfd) while commands are queued; -1 before start().
	int command_fd() const noexcept { return command_event_fd_; }
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
	SpscQueue<PlcCommand, 16> commands_;
	int command_event_fd_ = -1;
	int stop_event_fd_ = -1;
	int listen_fd_ = -1;
	std::uint16_t bound_port_ = 0;
	std::thread thread_;

	std::atomic<std::uint64_t> accepted_{0}, refused_{0}, dropped_{0}, answered_{0}, exceptions_{0},
		queued_{0};
	std::atomic<unsigned> clients_now_{0};
};

} // namespace mfcd::motion
