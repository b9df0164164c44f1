#include "daemon/robot_link.hpp"

#include "daemon/log.hpp"

namespace mfcd::daemon {

void RobotLink::start(const motion::ModbusServerConfig& modbus, bool can_enabled, const motion::CanConfig& can) {
  modbus_ = std::make_unique<motion::ModbusServer>(modbus);
  modbus_->start();
  logf(LogLevel::Info, "Modbus/TCP on %s port %u", modbus.bind_address.c_str(), modbus_->port());
  reconfigure_can(can_enabled, can);
}

void RobotLink::reconfigure_can(bool can_enabled, const motion::CanConfig& can) {
  const bool same = can_ && can_enabled && can.interface == can_config_.interface && can.id_base == can_config_.id_base;
  if (same) return;
  can_.reset();
  can_config_ = can;
  if (!can_enabled) return;
  can_ = std::make_unique<motion::CanPublisher>(can);
  can_->start();
  can_->publish(last_);
}

void RobotLink::stop(std::chrono::milliseconds drain) {
  if (can_) can_->stop();
  if (!modbus_) return;
  // The last report (a final job's result, READY 0) reaches every connected PLC before the
  // connections close.
  if (!modbus_->drain(drain))
    logf(LogLevel::Notice, "stopping: a Modbus client did not poll within %lld ms",
         static_cast<long long>(drain.count()));
  modbus_->stop();
}

void RobotLink::publish(const motion::RobotReport& report) noexcept {
  last_ = report;
  if (modbus_) modbus_->publish(report);
  if (can_) can_->publish(report);
}

void RobotLink::lease_health(std::chrono::steady_clock::time_point until) noexcept {
  if (modbus_) modbus_->lease_health(until);
  if (can_) can_->lease_health(until);
}

std::optional<motion::PlcCommand> RobotLink::next_command() noexcept {
  return modbus_ ? modbus_->next_command() : std::nullopt;
}

motion::RobotPoseReading RobotLink::robot_pose() const noexcept {
  return modbus_ ? modbus_->robot_pose() : motion::RobotPoseReading{};
}

void RobotLink::describe(nlohmann::json& j) const {
  if (modbus_) {
    const auto s = modbus_->stats();
    j["modbus"] = {
        {"port", modbus_->port()},          {"clients", s.clients_now},         {"requests", s.requests_answered},
        {"commands", s.commands_queued},    {"exceptions", s.exceptions_sent},  {"idle_closed", s.connections_idle},
        {"evicted", s.connections_evicted}, {"dropped", s.connections_dropped}, {"serving", modbus_->serving()}};
  }
  if (can_) j["can"] = {{"interface", can_config_.interface}, {"state", motion::to_string(can_->state())}};
}

}  // namespace mfcd::daemon
