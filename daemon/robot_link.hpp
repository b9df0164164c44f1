#pragma once
// The robot link: the Modbus/TCP server and, when enabled, the SocketCAN publisher, started,
// fed and stopped together. The daemon's main thread is the single writer of the report both
// publish, and the single reader of the PLC's commands.
#include <chrono>
#include <memory>
#include <optional>

#include <nlohmann/json.hpp>

#include "motion/can_publisher.hpp"
#include "motion/modbus_server.hpp"

namespace mfcd::daemon {

class RobotLink {
 public:
  // Binds the Modbus server and starts the CAN publisher if `can_enabled`. Throws naming the
  // address or interface when either cannot start.
  void start(const motion::ModbusServerConfig& modbus, bool can_enabled, const motion::CanConfig& can);
  // A reload: CAN follows the new settings (restarted when they changed). The Modbus server keeps
  // its settings and its PLC connections until mfcd restarts.
  void reconfigure_can(bool can_enabled, const motion::CanConfig& can);
  // Publishes the last report, lets each connected PLC poll it (up to `drain`), then closes.
  void stop(std::chrono::milliseconds drain);

  void publish(const motion::RobotReport& report) noexcept;
  // HEARTBEAT and the CAN heartbeat run until `until` (see ModbusServer::lease_health).
  void lease_health(std::chrono::steady_clock::time_point until) noexcept;
  // False once the Modbus server's thread has died: no PLC can reach mfcd.
  bool serving() const noexcept { return modbus_ && modbus_->serving(); }

  int command_fd() const noexcept { return modbus_ ? modbus_->command_fd() : -1; }
  std::optional<motion::PlcCommand> next_command() noexcept;
  motion::RobotPoseReading robot_pose() const noexcept;
  std::uint16_t modbus_port() const noexcept { return modbus_ ? modbus_->port() : 0; }
  // For mfcd-ctl status: the "modbus" and "can" objects.
  void describe(nlohmann::json& status) const;

 private:
  std::unique_ptr<motion::ModbusServer> modbus_;
  std::unique_ptr<motion::CanPublisher> can_;
  motion::CanConfig can_config_;
  motion::RobotReport last_{};
};

}  // namespace mfcd::daemon
