// Private to the Modbus server: the state its thread owns, and the two halves of its work.
// modbus_server.cpp runs the connections (accept, read, time out, evict, close);
// modbus_requests.cpp answers one complete frame against the register map.
#pragma once

#include "motion/ip_allow_list.hpp"
#include "motion/modbus_server.hpp"
#include "motion/register_map.hpp"
#include "motion/request_guard.hpp"

#include <modbus/modbus.h>
#include <poll.h>

#include <chrono>
#include <cstdint>
#include <optional>
#include <vector>

namespace mfcd::motion {

struct ModbusServer::Impl {
  using Clock = std::chrono::steady_clock;

  struct Client {
    UniqueFd fd;
    std::size_t have = 0;                // bytes of the current frame received
    std::size_t need = kMbapHeaderSize;  // bytes the current frame needs
    Clock::time_point frame_started;     // when its first byte arrived
    Clock::time_point last_request;      // accept, or the last complete frame
    std::uint64_t seen = 0;              // publish count of the report its last request read
    std::uint8_t buf[kMaxAduSize];
  };
  enum class CloseReason { PeerClosed, Dropped, Idle, Evicted };

  explicit Impl(ModbusServer& server);
  ~Impl();
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  // --- connections (modbus_server.cpp) ---
  // One poll() round. False when the server is to stop (stop event or poll failure).
  bool serve_once();
  void advance_heartbeat(Clock::time_point now);
  // Closes timed-out clients; returns the earliest instant a timeout may fire next.
  Clock::time_point expire_clients(Clock::time_point now, Clock::time_point deadline);
  void accept_clients();
  Client* free_slot(Clock::time_point now);
  void read_client(Client& c);
  void close_client(Client& c, CloseReason why);
  void update_least_seen() noexcept;

  // --- requests (modbus_requests.cpp) ---
  // Copies the daemon's latest report into the register map; returns it.
  RobotReport refresh_registers();
  void handle_frame(Client& c, std::size_t size);
  // For a write covering COMMAND: the command to queue, or the exception refusing it.
  ModbusException decide_command(const RegisterWrite& w, const RobotReport& report, std::optional<PlcCommand>& command);
  // For a write covering PICK_RESULT: the report to queue (none for 0 or a repeat), or the
  // exception refusing it.
  ModbusException decide_pick_result(const RegisterWrite& w, const RobotReport& report,
                                     std::optional<PlcCommand>& result);
  // The control block as the write `w` would leave it.
  void control_after(const RegisterWrite& w, std::uint16_t (&control)[reg::kControlEnd]) const;
  bool queue_full() const noexcept;
  // For a write into the robot pose block: false (refuse) when the block it would leave is
  // invalid; else publishes the pose.
  bool write_robot_pose(const RegisterWrite& w);
  void queue_command(const PlcCommand& command);
  void send_exception(Client& c, std::uint8_t function, ModbusException code);

  ModbusServer& server;
  const ModbusServerConfig& config;
  modbus_t* ctx = nullptr;
  modbus_mapping_t* map = nullptr;
  IpAllowList allow;
  std::vector<Client> clients;
  std::vector<pollfd> fds;
  std::uint64_t report_count = 0;  // publish count read by the last refresh_registers()

  std::uint16_t heartbeat = 0;
  Clock::time_point next_beat;
  bool job_pending = false;
  std::uint16_t last_job = 0;
  std::uint16_t last_command_result = 0;
  // The pick the registers show: rank shown_rank of job shown_job's ranked list (NEXT
  // advances it at once; a new job starts at the rank the daemon published).
  std::uint16_t shown_job = 0;
  std::uint16_t shown_rank = 0;
  // The last pick a PICK_RESULT was taken for: a repeat of it is acknowledged, not queued.
  std::uint16_t reported_job = 0;
  std::uint16_t reported_rank = 0;
};

}  // namespace mfcd::motion
