#include "motion/can_publisher.hpp"

#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <syslog.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <utility>

namespace mfcd::motion {

using Clock = std::chrono::steady_clock;

std::string CanConfig::validate() const {
  if (interface.empty() || interface.size() >= IFNAMSIZ)
    return "can interface '" + interface + "': name must be 1.." + std::to_string(IFNAMSIZ - 1) + " characters";
  if (id_base + kCanPickCOffset > CAN_SFF_MASK)
    return "can id_base " + std::to_string(id_base) + ": frames would exceed the 11-bit id range";
  if (heartbeat_period.count() < 10) return "can heartbeat_period_ms must be >= 10";
  if (retry_interval.count() < 10) return "can retry_interval_ms must be >= 10";
  return {};
}

const char* to_string(CanLinkState state) noexcept {
  switch (state) {
    case CanLinkState::Down:
      return "down";
    case CanLinkState::Up:
      return "up";
    case CanLinkState::ErrorPassive:
      return "error-passive";
    case CanLinkState::BusOff:
      return "bus-off";
  }
  return "?";
}

CanPublisher::CanPublisher(CanConfig config) : config_(std::move(config)) {
  if (std::string e = config_.validate(); !e.empty()) throw std::invalid_argument(e);
  wake_fd_.reset(::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK));
  stop_fd_.reset(::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK));
  if (!wake_fd_ || !stop_fd_)
    throw std::runtime_error(std::string("can: cannot create eventfd: ") + std::strerror(errno));
}

CanPublisher::~CanPublisher() {
  stop();  // the thread is gone before the members close their descriptors
}

void CanPublisher::start() {
  if (!thread_.joinable()) thread_ = std::thread([this] { run(); });
}

void CanPublisher::stop() {
  if (!thread_.joinable()) return;
  const std::uint64_t one = 1;
  [[maybe_unused]] ssize_t n = ::write(stop_fd_.get(), &one, sizeof(one));
  thread_.join();
  std::uint64_t drain;
  n = ::read(stop_fd_.get(), &drain, sizeof(drain));
  close_link();
}

void CanPublisher::publish(const RobotReport& report) noexcept {
  report_.publish(report);
  const std::uint64_t one = 1;
  [[maybe_unused]] ssize_t n = ::write(wake_fd_.get(), &one, sizeof(one));  // non-blocking eventfd
}

std::string CanPublisher::last_error() const {
  std::lock_guard lock(error_mutex_);
  return last_error_;
}

CanPublisherStats CanPublisher::stats() const noexcept {
  return {sent_.load(), dropped_.load(), picks_.load(), attempts_.load(), bus_offs_.load()};
}

void CanPublisher::set_error(std::string message) {
  std::lock_guard lock(error_mutex_);
  if (message != last_error_) syslog(LOG_WARNING, "%s", message.c_str());
  last_error_ = std::move(message);
}

void CanPublisher::set_state(CanLinkState s) {
  const CanLinkState old = state_.exchange(s);
  if (old != s)
    syslog(s == CanLinkState::Up ? LOG_NOTICE : LOG_WARNING, "can %s: link %s", config_.interface.c_str(),
           to_string(s));
}

bool CanPublisher::open_link() {
  attempts_.fetch_add(1);
  const std::string where = "can interface '" + config_.interface + "': ";
  const unsigned index = if_nametoindex(config_.interface.c_str());
  if (index == 0) {
    set_error(where + std::strerror(errno));
    return false;
  }
  UniqueFd can_socket(::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW));
  const int fd = can_socket.get();
  if (!can_socket) {
    const int err = errno;
    // RestrictAddressFamilies= in the systemd unit refuses AF_CAN unless the can.conf drop-in
    // is installed (docs/operations.md, "systemd").
    set_error(where + "cannot open CAN_RAW socket: " + std::strerror(err) +
              (err == EAFNOSUPPORT ? " (AF_CAN not permitted: install systemd/mfcd.service.d/can.conf)" : ""));
    return false;
  }
  // Receive no data frames, only the controller errors that change the link state.
  ::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, nullptr, 0);
  const can_err_mask_t errors = CAN_ERR_BUSOFF | CAN_ERR_CRTL | CAN_ERR_RESTARTED | CAN_ERR_TX_TIMEOUT;
  ::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &errors, sizeof(errors));
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = static_cast<int>(index);
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) < 0) {
    set_error(where + "cannot bind: " + std::strerror(errno));
    return false;
  }
  ifreq ifr{};
  std::strncpy(ifr.ifr_name, config_.interface.c_str(), IFNAMSIZ - 1);
  if (::ioctl(fd, SIOCGIFFLAGS, &ifr) == 0 && !(ifr.ifr_flags & IFF_UP)) {
    set_error(where + std::strerror(ENETDOWN));
    return false;
  }
  socket_fd_ = std::move(can_socket);
  set_error({});
  set_state(CanLinkState::Up);
  return true;
}

void CanPublisher::close_link() {
  socket_fd_.reset();
  set_state(CanLinkState::Down);
}

bool CanPublisher::send(const can_frame& frame) {
  if (!socket_fd_ || state_.load() == CanLinkState::BusOff) {
    dropped_.fetch_add(1);
    return false;
  }
  if (::write(socket_fd_.get(), &frame, sizeof(frame)) == static_cast<ssize_t>(sizeof(frame))) {
    sent_.fetch_add(1);
    return true;
  }
  const int err = errno;
  dropped_.fetch_add(1);
  const std::string where = "can interface '" + config_.interface + "': ";
  if (err == ENETDOWN || err == ENODEV || err == ENXIO) {
    set_error(where + std::strerror(err));
    close_link();
  } else if (err == ENOBUFS || err == EAGAIN) {
    // Transmit queue full: nobody acknowledges (no other node, or the controller is
    // off the bus). Report, keep the socket, and let the retry timer try again.
    set_error(where + "transmit queue full (no acknowledgement on the bus?)");
  } else {
    set_error(where + "send failed: " + std::strerror(err));
  }
  return false;
}

void CanPublisher::drain_errors() {
  can_frame f;
  for (;;) {
    const ssize_t n = ::read(socket_fd_.get(), &f, sizeof(f));
    if (n < 0) {
      if (errno == ENETDOWN || errno == ENODEV) {
        set_error("can interface '" + config_.interface + "': " + std::strerror(errno));
        close_link();
      }
      return;
    }
    if (n != sizeof(f)) continue;
    switch (classify_error_frame(f)) {
      case CanErrorKind::BusOff:
        bus_offs_.fetch_add(1);
        set_error("can interface '" + config_.interface + "': controller is bus-off");
        set_state(CanLinkState::BusOff);
        break;
      case CanErrorKind::ErrorPassive:
        set_state(CanLinkState::ErrorPassive);
        break;
      case CanErrorKind::Restarted:
        set_state(CanLinkState::Up);
        break;
      case CanErrorKind::Other:
        break;
    }
  }
}

void CanPublisher::run() {
  std::uint16_t heartbeat = 0;
  std::uint8_t pick_sequence = 0;
  std::uint16_t last_pick_job = 0, last_pick_rank = 0;
  std::uint16_t last_status = 0;
  std::uint16_t last_status_job = 0, last_status_error = 0, last_status_objects = 0;
  bool status_known = false;
  // The release does not change while the publisher runs: one frame, built once.
  const can_frame version = encode_version(config_.software_version, config_.software_patch, config_.id_base);
  Clock::time_point next_beat = Clock::now();
  Clock::time_point next_retry = Clock::now();

  for (;;) {
    const Clock::time_point now = Clock::now();
    if (!socket_fd_ && now >= next_retry) {
      if (!open_link()) next_retry = now + config_.retry_interval;
    } else if (state_.load() == CanLinkState::BusOff && now >= next_retry) {
      // Bus-off recovery belongs to the driver (restart-ms); probe whether it is back.
      set_state(CanLinkState::ErrorPassive);
      next_retry = now + config_.retry_interval;
    }

    const RobotReport report = report_.read();
    const std::uint16_t status = can_status_word(report);
    const bool changed = !status_known || status != last_status || report.job_id != last_status_job ||
                         report.error_code != last_status_error || report.objects_remaining != last_status_objects;
    const bool beat_due = now >= next_beat;
    const bool healthy = now.time_since_epoch().count() < health_until_ns_.load(std::memory_order_acquire);
    if (beat_due) {
      // The version frame follows each heartbeat under the same lease, so a receiver that
      // starts listening learns mfcd's release within one heartbeat period.
      if (healthy) {
        send(encode_heartbeat(heartbeat++, report, config_.id_base));
        send(version);
      }
      next_beat += config_.heartbeat_period;
      if (next_beat < now) next_beat = now + config_.heartbeat_period;
    }
    if ((beat_due || changed) && send(encode_status(report, config_.id_base))) {
      status_known = true;
      last_status = status;
      last_status_job = report.job_id;
      last_status_error = report.error_code;
      last_status_objects = report.objects_remaining;
    }
    // A new job's pick, or the next pick of the same job (NEXT on the Modbus link).
    const bool new_pick = report.pick_valid && report.job_id != 0 &&
                          (report.job_id != last_pick_job || report.pick_rank != last_pick_rank);
    if (new_pick) {
      const auto frames = encode_pick(report, pick_sequence, config_.id_base);
      bool done = true;  // sent, or never sendable
      if (!frames) {
        set_error("can: pick for job " + std::to_string(report.job_id) + " is outside the CAN signal ranges; not sent");
      } else if (send((*frames)[0]) && send((*frames)[1]) && send((*frames)[2])) {
        picks_.fetch_add(1);
        ++pick_sequence;
      } else {
        done = false;
      }
      if (done) {
        last_pick_job = report.job_id;
        last_pick_rank = report.pick_rank;
      }
    }

    pollfd fds[3] = {{stop_fd_.get(), POLLIN, 0}, {wake_fd_.get(), POLLIN, 0}, {socket_fd_.get(), POLLIN, 0}};
    Clock::time_point deadline = next_beat;
    if (!socket_fd_ || state_.load() == CanLinkState::BusOff) deadline = std::min(deadline, next_retry);
    // A status or pick that could not be sent is retried at the latest after retry_interval.
    const bool pick_unsent = report.pick_valid && report.job_id != 0 &&
                             (report.job_id != last_pick_job || report.pick_rank != last_pick_rank);
    if (socket_fd_ && (!status_known || pick_unsent)) deadline = std::min(deadline, now + config_.retry_interval);
    const auto wait = std::chrono::ceil<std::chrono::milliseconds>(deadline - Clock::now()).count();
    const int ready = ::poll(fds, socket_fd_ ? 3 : 2, static_cast<int>(std::max<long>(wait, 0)));
    if (ready <= 0) continue;
    if (fds[0].revents) return;
    if (fds[1].revents) {
      std::uint64_t count;
      [[maybe_unused]] ssize_t n = ::read(wake_fd_.get(), &count, sizeof(count));
    }
    if (socket_fd_ && fds[2].revents) drain_errors();
  }
}

}  // namespace mfcd::motion
