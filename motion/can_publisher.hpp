// Publishes the robot link's status, heartbeat, release (MFCD_Version) and picks on a SocketCAN
// interface.
//
// Runs its own thread. The daemon's result writer calls publish() (seqlock store plus an
// eventfd write: no lock, no allocation, never blocks). Link-down (interface missing or
// down, ENETDOWN/ENODEV) and bus-off (CAN_ERR_BUSOFF error frames, ENOBUFS while the
// controller is off the bus) are reported through state()/last_error() and syslog, and the
// link is retried every retry_interval.
#pragma once

#include "base/unique_fd.hpp"
#include "motion/can_frames.hpp"
#include "motion/robot_report.hpp"
#include "motion/seqlock.hpp"

#include <atomic>
#include <chrono>
#include <cstdint>
#include <limits>
#include <mutex>
#include <string>
#include <thread>

namespace mfcd::motion {

struct CanConfig {
  std::string interface = "can0";
  canid_t id_base = kCanDefaultBase;  // 11-bit; frames use base .. base+0x12
  std::chrono::milliseconds heartbeat_period{1000};
  std::chrono::milliseconds retry_interval{1000};
  // mfcd's release sent in MFCD_Version, packed as the Modbus registers 53..54 hold it
  // (ModbusServerConfig): major << 8 | minor, and patch. 0 and 0 when the daemon's version
  // string is not "major.minor.patch".
  std::uint16_t software_version = 0;
  std::uint16_t software_patch = 0;

  std::string validate() const;
};

enum class CanLinkState { Down, Up, ErrorPassive, BusOff };
const char* to_string(CanLinkState state) noexcept;

struct CanPublisherStats {
  std::uint64_t frames_sent = 0;
  std::uint64_t frames_dropped = 0;  // not sent: link down, bus-off, tx queue full
  std::uint64_t picks_sent = 0;
  std::uint64_t link_attempts = 0;  // socket open/bind attempts
  std::uint64_t bus_off_events = 0;
};

class CanPublisher {
 public:
  explicit CanPublisher(CanConfig config);  // throws std::invalid_argument
  ~CanPublisher();
  CanPublisher(const CanPublisher&) = delete;
  CanPublisher& operator=(const CanPublisher&) = delete;

  void start();
  void stop();

  // Single writer. A report whose job_id differs from the last one sent and that has
  // pick_valid set is sent as a pick; status goes out on every change and with each heartbeat.
  void publish(const RobotReport& report) noexcept;

  // The heartbeat frame, and the version frame right after it, go out only while now < `until`
  // (the daemon renews this lease while its threads move, as for the Modbus HEARTBEAT): a
  // receiver's heartbeat timeout then means mfcd is down or hung. Until the first lease the
  // publisher beats on its own.
  void lease_health(std::chrono::steady_clock::time_point until) noexcept {
    health_until_ns_.store(until.time_since_epoch().count(), std::memory_order_release);
  }

  CanLinkState state() const noexcept { return state_.load(); }
  std::string last_error() const;
  CanPublisherStats stats() const noexcept;

 private:
  void run();
  bool open_link();
  void close_link();
  bool send(const can_frame& frame);
  void drain_errors();
  void set_error(std::string message);
  void set_state(CanLinkState s);

  CanConfig config_;
  SeqlockSnapshot<RobotReport> report_;
  UniqueFd wake_fd_;  // publish() -> thread
  UniqueFd stop_fd_;
  UniqueFd socket_fd_;
  std::thread thread_;
  std::atomic<CanLinkState> state_{CanLinkState::Down};
  std::atomic<std::int64_t> health_until_ns_{std::numeric_limits<std::int64_t>::max()};
  mutable std::mutex error_mutex_;  // diagnostics only; never taken by publish()
  std::string last_error_;
  std::atomic<std::uint64_t> sent_{0}, dropped_{0}, picks_{0}, attempts_{0}, bus_offs_{0};
};

}  // namespace mfcd::motion
