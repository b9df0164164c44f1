#include "motion/modbus_server.h"

#include "motion/ip_allow_list.h"
#include "motion/register_map.h"
#include "motion/request_guard.h"

#include <arpa/inet.h>
#include <cmath>
#include <fcntl.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
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

std::string ModbusServerConfig::validate() const
{
	in6_addr scratch;
	if (inet_pton(AF_INET, bind_address.c_str(), &scratch) != 1 &&
	    inet_pton(AF_INET6, bind_address.c_str(), &scratch) != 1)
		return "modbus bind_address '" + bind_address + "': not an IPv4 or IPv6 address";
	if (max_clients < 1 || max_clients > 64)
		return "modbus max_clients " + std::to_string(max_clients) + ": must be 1..64";
	if (frame_timeout.count() < 10 || frame_timeout.count() > 60000)
		return "modbus frame_timeout_ms " + std::to_string(frame_timeout.count()) + ": must be 10..60000";
	try {
		IpAllowList check(allow_list);
	} catch (const std::invalid_argument &e) {
		return e.what();
	}
	return {};
}

namespace {

constexpr RegisterPolicy kPolicy{reg::kBlockSize, 0, reg::kWritableEnd, reg::kRobotPoseBegin, reg::kRobotPoseEnd};

struct Client {
	int fd = -1;
	std::size_t have = 0;                  // bytes of the current frame received
	std::size_t need = kMbapHeaderSize;    // bytes the current frame needs
	Clock::time_point frame_started;       // when its first byte arrived
	std::uint8_t buf[kMaxAduSize];
};

std::uint16_t be16(const std::uint8_t *p) noexcept
{
	return static_cast<std::uint16_t>((p[0] << 8) | p[1]);
}

} // namespace

struct ModbusServer::Impl {
	explicit Impl(const ModbusServerConfig &config) : allow(config.allow_list), clients(config.max_clients)
	{
		ctx = modbus_new_tcp("127.0.0.1", 502); // only used to build replies; never connects
		map = modbus_mapping_new(0, 0, reg::kBlockSize, reg::kBlockSize);
		if (!ctx || !map)
			throw std::runtime_error("modbus: cannot allocate libmodbus context");
	}
	~Impl()
	{
		for (Client &c : clients)
			if (c.fd >= 0)
				::close(c.fd);
		modbus_mapping_free(map);
		modbus_free(ctx);
	}

	modbus_t *ctx = nullptr;
	modbus_mapping_t *map = nullptr;
	IpAllowList allow;
	std::vector<Client> clients;
	std::vector<pollfd> fds;

	std::uint16_t heartbeat = 0;
	Clock::time_point next_beat;
	bool job_pending = false;
	std::uint16_t last_job = 0;
	std::uint16_t last_command_result = 0;
};

ModbusServer::ModbusServer(ModbusServerConfig config) : config_(std::move(config))
{
	if (std::string error = config_.validate(); !error.empty())
		throw std::invalid_argument(error);
	impl_ = std::make_unique<Impl>(config_);
}

ModbusServer::~ModbusServer()
{
	stop();
	if (command_event_fd_ >= 0)
		::close(command_event_fd_);
}

void ModbusServer::start()
{
	if (running())
		return;
	const std::string where = config_.bind_address + ":" + std::to_string(config_.port);
	const auto fail = [&](const char *what) {
		const int err = errno;
		if (listen_fd_ >= 0)
			::close(listen_fd_);
		listen_fd_ = -1;
		return std::system_error(err, std::generic_category(), std::string("modbus: cannot ") + what + " " + where);
	};

	sockaddr_storage addr{};
	socklen_t addr_len = 0;
	auto *in4 = reinterpret_cast<sockaddr_in *>(&addr);
	auto *in6 = reinterpret_cast<sockaddr_in6 *>(&addr);
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

	listen_fd_ = ::socket(addr.ss_family, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
	if (listen_fd_ < 0)
		throw fail("open socket for");
	const int one = 1;
	::setsockopt(listen_fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
	if (::bind(listen_fd_, reinterpret_cast<sockaddr *>(&addr), addr_len) < 0)
		throw fail("bind");
	if (::listen(listen_fd_, 16) < 0)
		throw fail("listen on");
	sockaddr_storage bound{};
	socklen_t bound_len = sizeof(bound);
	::getsockname(listen_fd_, reinterpret_cast<sockaddr *>(&bound), &bound_len);
	bound_port_ = ntohs(bound.ss_family == AF_INET ? reinterpret_cast<sockaddr_in *>(&bound)->sin_port
	                                               : reinterpret_cast<sockaddr_in6 *>(&bound)->sin6_port);

	stop_event_fd_ = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
	if (command_event_fd_ < 0)
		command_event_fd_ = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
	if (stop_event_fd_ < 0 || command_event_fd_ < 0)
		throw fail("create eventfd for");

	impl_->fds.reserve(2 + impl_->clients.size());
	impl_->next_beat = Clock::now() + std::chrono::seconds(1);
	syslog(LOG_INFO, "modbus: listening on %s:%u, word order %s, %u clients max",
	       config_.bind_address.c_str(), bound_port_, std::string(to_string(config_.word_order)).c_str(),
	       config_.max_clients);
	thread_ = std::thread([this] { run(); });
}

void ModbusServer::stop()
{
	if (!thread_.joinable())
		return;
	const std::uint64_t one = 1;
	[[maybe_unused]] ssize_t n = ::write(stop_event_fd_, &one, sizeof(one));
	thread_.join();
	for (Client &c : impl_->clients) {
		if (c.fd >= 0)
			::close(c.fd);
		c.fd = -1;
	}
	clients_now_.store(0);
	::close(listen_fd_);
	::close(stop_event_fd_);
	listen_fd_ = stop_event_fd_ = -1;
}

std::optional<PlcCommand> ModbusServer::next_command() noexcept
{
	// Drain the eventfd before popping: a command pushed after the drain re-arms it, so a
	// queued command never goes without a wake-up (at worst one spurious wake-up).
	if (command_event_fd_ >= 0) {
		std::uint64_t count;
		[[maybe_unused]] ssize_t n = ::read(command_event_fd_, &count, sizeof(count));
	}
	return commands_.pop();
}

ModbusServerStats ModbusServer::stats() const noexcept
{
	ModbusServerStats s;
	s.connections_accepted = accepted_.load();
	s.connections_refused = refused_.load();
	s.connections_dropped = dropped_.load();
	s.requests_answered = answered_.load();
	s.exceptions_sent = exceptions_.load();
	s.commands_queued = queued_.load();
	s.clients_now = clients_now_.load();
	return s;
}

void ModbusServer::run() noexcept
{
	Impl &m = *impl_;
	std::uint16_t *regs = m.map->tab_registers;

	const auto close_client = [&](Client &c, bool dropped) {
		// Count before closing, so whoever sees the close also sees the count.
		clients_now_.fetch_sub(1);
		if (dropped)
			dropped_.fetch_add(1);
		::close(c.fd);
		c.fd = -1;
		c.have = 0;
		c.need = kMbapHeaderSize;
	};

	// Copies the daemon's latest report into the status block, so every read sees one
	// consistent snapshot.
	const auto refresh_registers = [&] {
		const RobotReport r = report_.read();
		if (m.job_pending && r.job_id == m.last_job)
			m.job_pending = false;
		std::uint16_t status = 0;
		if (r.ready && !m.job_pending && r.error_code == 0)
			status |= reg::kReady;
		if (m.job_pending)
			status |= reg::kBusy;
		if (!m.job_pending && m.last_job != 0 && r.job_id == m.last_job)
			status |= reg::kDone;
		if (r.error_code != 0)
			status |= reg::kError;
		if (r.pick_valid)
			status |= reg::kPickValid;
		if (r.vision_ok)
			status |= reg::kVisionOk;
		regs[reg::kStatus] = status;
		regs[reg::kJobIdEcho] = r.job_id;
		regs[reg::kHeartbeat] = m.heartbeat;
		regs[reg::kErrorCode] = r.error_code;
		regs[reg::kRecipeEcho] = r.recipe_id;
		regs[reg::kObjectsRemaining] = r.objects_remaining;
		regs[reg::kCycleTimeMs] = r.cycle_time_ms;
		regs[reg::kCandidateIndex] = r.candidate_index;
		regs[reg::kCandidateCount] = r.candidate_count;
		regs[reg::kWordOrder] = static_cast<std::uint16_t>(config_.word_order);
		regs[reg::kMapVersionReg] = reg::kMapVersion;
		regs[reg::kLastCommandResult] = m.last_command_result;
		const auto put = [&](std::uint16_t at, float v) {
			const auto words = encode_float(v, config_.word_order);
			regs[at] = words[0];
			regs[at + 1] = words[1];
		};
		const bool valid = r.pick_valid != 0;
		put(reg::kPickX, valid ? r.pick.x_mm : 0.0f);
		put(reg::kPickY, valid ? r.pick.y_mm : 0.0f);
		put(reg::kPickZ, valid ? r.pick.z_mm : 0.0f);
		put(reg::kPickRx, valid ? r.pick.rx_deg : 0.0f);
		put(reg::kPickRy, valid ? r.pick.ry_deg : 0.0f);
		put(reg::kPickRz, valid ? r.pick.rz_deg : 0.0f);
		put(reg::kScore, valid ? r.score : 0.0f);
		put(reg::kTestVector, reg::kTestVectorValue);
		std::memcpy(m.map->tab_input_registers, regs, reg::kBlockSize * sizeof(std::uint16_t));
		return r;
	};

	const auto send_exception = [&](Client &c, std::uint8_t function, ModbusException code) {
		std::uint8_t rsp[9] = {c.buf[0], c.buf[1], 0, 0, 0, 3, c.buf[6],
		                       static_cast<std::uint8_t>(function | 0x80), static_cast<std::uint8_t>(code)};
		exceptions_.fetch_add(1);
		if (::send(c.fd, rsp, sizeof(rsp), MSG_NOSIGNAL | MSG_DONTWAIT) != sizeof(rsp))
			close_client(c, true);
	};

	const auto handle_frame = [&](Client &c, std::size_t size) {
		const RobotReport report = refresh_registers();
		GuardVerdict v = check_request(std::span<const std::uint8_t>(c.buf, size), kPolicy);
		if (v.exception != ModbusException::None) {
			send_exception(c, v.function, v.exception);
			return;
		}

		// A write covering the command register is a command: decide on it before any
		// register changes, so a refused command leaves the map untouched.
		std::optional<PlcCommand> command;
		const RegisterWrite &w = v.write;
		if (w.count > 0 && w.address <= reg::kCommand && reg::kCommand < w.address + w.count) {
			std::uint16_t control[reg::kControlEnd];
			std::copy(regs, regs + reg::kControlEnd, control);
			for (std::uint16_t i = 0; i < w.count && w.address + i < reg::kControlEnd; ++i)
				control[w.address + i] = be16(w.values + 2 * i);
			ModbusException refuse = ModbusException::None;
			const auto code = static_cast<reg::Command>(control[reg::kCommand]);
			if (code == reg::Command::Trigger) {
				if (control[reg::kJobId] == 0 || control[reg::kJobId] == m.last_job ||
				    control[reg::kMode] > reg::kModeMax)
					refuse = ModbusException::IllegalDataValue;
				else if (m.job_pending || !report.ready || report.error_code != 0 ||
				         commands_.size_approx() >= 16)
					refuse = ModbusException::ServerDeviceBusy;
				else
					command = PlcCommand{PlcCommand::Kind::Trigger, control[reg::kJobId],
					                     control[reg::kRecipeId], control[reg::kMode]};
			} else if (code == reg::Command::Reset) {
				if (commands_.size_approx() >= 16)
					refuse = ModbusException::ServerDeviceBusy;
				else
					command = PlcCommand{PlcCommand::Kind::Reset, control[reg::kJobId],
					                     control[reg::kRecipeId], control[reg::kMode]};
			} else if (code != reg::Command::None) {
				refuse = ModbusException::IllegalDataValue;
			}
			m.last_command_result = static_cast<std::uint16_t>(refuse);
			regs[reg::kLastCommandResult] = m.last_command_result;
			if (refuse != ModbusException::None) {
				send_exception(c, v.function, refuse);
				return;
			}
		}

		// A write into the robot pose block is checked as the block it would leave: a valid flag
		// other than 0/1 or a non-finite float is refused and nothing is written.
		const bool pose_write = w.count > 0 && w.address < reg::kRobotPoseEnd && w.address + w.count > reg::kRobotPoseBegin;
		std::uint16_t pose_block[reg::kRobotPoseEnd - reg::kRobotPoseBegin];
		if (pose_write) {
			std::copy(regs + reg::kRobotPoseBegin, regs + reg::kRobotPoseEnd, pose_block);
			for (std::uint16_t i = 0; i < w.count; ++i)
				pose_block[w.address + i - reg::kRobotPoseBegin] = be16(w.values + 2 * i);
			bool ok = pose_block[reg::kRobotPoseValid - reg::kRobotPoseBegin] <= 1;
			for (std::uint16_t at = reg::kRobotPoseX; at < reg::kRobotPoseValid; at += 2) {
				const std::uint16_t *p = pose_block + (at - reg::kRobotPoseBegin);
				ok = ok && std::isfinite(decode_float(p[0], p[1], config_.word_order));
			}
			if (!ok) {
				send_exception(c, v.function, ModbusException::IllegalDataValue);
				return;
			}
			// Published before the answer: once the PLC has its acknowledgement, mfcd sees the pose.
			RobotPoseReading p = robot_pose_.read();
			const auto f = [&](std::uint16_t at) {
				const std::uint16_t *q = pose_block + (at - reg::kRobotPoseBegin);
				return decode_float(q[0], q[1], config_.word_order);
			};
			++p.writes;
			p.valid = pose_block[reg::kRobotPoseValid - reg::kRobotPoseBegin];
			p.sequence = pose_block[reg::kRobotPoseSeq - reg::kRobotPoseBegin];
			p.x_mm = f(reg::kRobotPoseX), p.y_mm = f(reg::kRobotPoseY), p.z_mm = f(reg::kRobotPoseZ);
			p.rx_deg = f(reg::kRobotPoseRx), p.ry_deg = f(reg::kRobotPoseRy), p.rz_deg = f(reg::kRobotPoseRz);
			robot_pose_.publish(p);
		}
		modbus_set_socket(m.ctx, c.fd);
		if (modbus_reply(m.ctx, c.buf, static_cast<int>(size), m.map) < 0) {
			close_client(c, true);
		} else {
			answered_.fetch_add(1);
		}
		if (command) {
			regs[reg::kCommand] = 0; // reads back 0 once taken
			if (command->kind == PlcCommand::Kind::Trigger) {
				m.job_pending = true;
				m.last_job = command->job_id;
			} else {
				m.job_pending = false;
			}
			commands_.push(*command);
			queued_.fetch_add(1);
			const std::uint64_t one = 1;
			[[maybe_unused]] ssize_t n = ::write(command_event_fd_, &one, sizeof(one));
			refresh_registers();
		}
	};

	const auto read_client = [&](Client &c) {
		while (c.fd >= 0) {
			const ssize_t n = ::recv(c.fd, c.buf + c.have, c.need - c.have, MSG_DONTWAIT);
			if (n == 0) {
				close_client(c, c.have != 0); // closed mid-frame counts as dropped
				return;
			}
			if (n < 0) {
				if (errno == EINTR)
					continue;
				if (errno != EAGAIN && errno != EWOULDBLOCK)
					close_client(c, true);
				return;
			}
			if (c.have == 0)
				c.frame_started = Clock::now();
			c.have += static_cast<std::size_t>(n);
			if (c.have < c.need)
				continue;
			if (c.need == kMbapHeaderSize) {
				const std::size_t size = mbap_frame_size(std::span<const std::uint8_t, kMbapHeaderSize>(c.buf, kMbapHeaderSize));
				if (size == 0) {
					// No trustworthy frame boundary after a bad header: drop the connection.
					close_client(c, true);
					return;
				}
				c.need = size;
				if (c.have < c.need)
					continue;
			}
			const std::size_t size = c.have;
			c.have = 0;
			c.need = kMbapHeaderSize;
			handle_frame(c, size);
		}
	};

	const auto accept_clients = [&] {
		for (;;) {
			sockaddr_storage peer{};
			socklen_t peer_len = sizeof(peer);
			const int fd = ::accept4(listen_fd_, reinterpret_cast<sockaddr *>(&peer), &peer_len,
			                         SOCK_NONBLOCK | SOCK_CLOEXEC);
			if (fd < 0)
				return;
			if (!m.allow.allows(reinterpret_cast<sockaddr *>(&peer))) {
				char text[INET6_ADDRSTRLEN] = "?";
				const void *a = peer.ss_family == AF_INET
				                        ? static_cast<const void *>(&reinterpret_cast<sockaddr_in *>(&peer)->sin_addr)
				                        : static_cast<const void *>(&reinterpret_cast<sockaddr_in6 *>(&peer)->sin6_addr);
				inet_ntop(peer.ss_family, a, text, sizeof(text));
				syslog(LOG_WARNING, "modbus: refused client %s: not in allow_list", text);
				refused_.fetch_add(1);
				::close(fd);
				continue;
			}
			auto slot = std::find_if(m.clients.begin(), m.clients.end(), [](const Client &c) { return c.fd < 0; });
			if (slot == m.clients.end()) {
				syslog(LOG_WARNING, "modbus: refused client: max_clients %u reached", config_.max_clients);
				refused_.fetch_add(1);
				::close(fd);
				continue;
			}
			const int one = 1;
			::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));
			slot->fd = fd;
			slot->have = 0;
			slot->need = kMbapHeaderSize;
			accepted_.fetch_add(1);
			clients_now_.fetch_add(1);
		}
	};

	for (;;) {
		const Clock::time_point now = Clock::now();
		while (now >= m.next_beat) {
			++m.heartbeat;
			m.next_beat += std::chrono::seconds(1);
		}
		Clock::time_point deadline = m.next_beat;
		for (Client &c : m.clients) {
			if (c.fd < 0 || c.have == 0)
				continue;
			if (now - c.frame_started > config_.frame_timeout) {
				close_client(c, true);
				continue;
			}
			deadline = std::min(deadline, c.frame_started + config_.frame_timeout);
		}

		m.fds.clear();
		m.fds.push_back({stop_event_fd_, POLLIN, 0});
		m.fds.push_back({listen_fd_, POLLIN, 0});
		for (const Client &c : m.clients)
			if (c.fd >= 0)
				m.fds.push_back({c.fd, POLLIN, 0});
		const auto wait = std::chrono::ceil<std::chrono::milliseconds>(deadline - now).count();
		const int ready = ::poll(m.fds.data(), m.fds.size(), static_cast<int>(std::max<long>(wait, 1)));
		if (ready < 0 && errno != EINTR) {
			syslog(LOG_ERR, "modbus: poll failed: %s", std::strerror(errno));
			return;
		}
		if (ready <= 0)
			continue;
		if (m.fds[0].revents)
			return;
		if (m.fds[1].revents & POLLIN)
			accept_clients();
		for (std::size_t i = 2; i < m.fds.size(); ++i) {
			if (!m.fds[i].revents)
				continue;
			auto c = std::find_if(m.clients.begin(), m.clients.end(),
			                      [&](const Client &cl) { return cl.fd == m.fds[i].fd; });
			if (c != m.clients.end())
				read_client(*c);
		}
	}
}

} // namespace mfcd::motion
