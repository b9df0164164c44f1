// The Modbus server's answer to one complete, framed request (see modbus_server_impl.hpp).
#include "motion/modbus_server_impl.hpp"
#include "motion/register_map.hpp"

#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>

namespace mfcd::motion {

namespace {

constexpr RegisterPolicy kPolicy{reg::kBlockSize, 0, reg::kWritableEnd, reg::kRobotPoseBegin, reg::kRobotPoseEnd};

std::uint16_t be16(const std::uint8_t* p) noexcept { return static_cast<std::uint16_t>((p[0] << 8) | p[1]); }

// PICK_VALID: the report has a pick to show. A result that asks for a second look or answers a
// gripper check has none, whatever pick_valid says.
bool shows_pick(const RobotReport& r) noexcept { return r.pick_valid != 0 && r.look_wanted == 0 && r.grip_state == 0; }

}  // namespace

// Every read sees one consistent snapshot of the daemon's report.
RobotReport ModbusServer::Impl::refresh_registers() {
  report_count = server.published_.load(std::memory_order_acquire);
  const RobotReport r = server.report_.read();
  std::uint16_t* regs = map->tab_registers;
  if (job_pending && r.job_id == last_job) job_pending = false;
  if (r.job_id != shown_job) {
    shown_job = r.job_id;
    shown_rank = 0;
  }
  shown_rank = std::max(shown_rank, r.pick_rank);
  std::uint16_t status = 0;
  if (r.ready && !job_pending && r.error_code == 0) status |= reg::kReady;
  if (job_pending) status |= reg::kBusy;
  if (!job_pending && last_job != 0 && r.job_id == last_job) status |= reg::kDone;
  if (r.error_code != 0) status |= reg::kError;
  const bool look = r.look_wanted != 0;
  const bool valid = shows_pick(r);
  if (valid) status |= reg::kPickValid;
  if (r.vision_ok) status |= reg::kVisionOk;
  if (look) status |= reg::kLookWanted;
  RankedPick shown{r.pick, r.score, r.candidate_index, 0};
  if (r.pick_count > 0 && shown_rank < r.pick_count) shown = r.ranked[shown_rank];
  regs[reg::kStatus] = status;
  regs[reg::kJobIdEcho] = r.job_id;
  regs[reg::kHeartbeat] = heartbeat;
  regs[reg::kErrorCode] = r.error_code;
  regs[reg::kRecipeEcho] = r.recipe_id;
  regs[reg::kObjectsRemaining] = r.objects_remaining;
  regs[reg::kCycleTimeMs] = r.cycle_time_ms;
  regs[reg::kCandidateIndex] = shown.candidate_index;
  regs[reg::kCandidateCount] = r.candidate_count;
  regs[reg::kWordOrder] = static_cast<std::uint16_t>(config.word_order);
  regs[reg::kMapVersionReg] = reg::kMapVersion;
  regs[reg::kLastCommandResult] = last_command_result;
  const auto put = [&](std::uint16_t at, float v) {
    const auto words = encode_float(v, config.word_order);
    regs[at] = words[0];
    regs[at + 1] = words[1];
  };
  // A pose's six float pairs from `first` on (X, Y, Z, RX, RY, RZ are consecutive), or 0.0.
  const auto put_pose = [&](std::uint16_t first, const PickPose& p, bool shown_pose) {
    const float v[6] = {p.x_mm, p.y_mm, p.z_mm, p.rx_deg, p.ry_deg, p.rz_deg};
    for (std::uint16_t i = 0; i < 6; ++i) put(static_cast<std::uint16_t>(first + 2 * i), shown_pose ? v[i] : 0.0f);
  };
  static_assert(reg::kPickRz == reg::kPickX + 10 && reg::kLookRz == reg::kLookX + 10 &&
                reg::kGripRz == reg::kGripX + 10);
  put_pose(reg::kPickX, shown.pick, valid);
  put(reg::kScore, valid ? shown.score : 0.0f);
  put(reg::kTestVector, reg::kTestVectorValue);
  regs[reg::kPickRank] = valid ? shown_rank : 0;
  regs[reg::kPicksLeft] =
      valid && r.pick_count > shown_rank ? static_cast<std::uint16_t>(r.pick_count - shown_rank - 1) : 0;
  regs[reg::kSnapshotCount] = r.snapshots_saved;
  regs[reg::kSoftwareVersion] = config.software_version;
  regs[reg::kSoftwarePatch] = config.software_patch;
  regs[reg::kLookReason] = look ? r.look_reason : 0;
  put_pose(reg::kLookX, r.look_pose, look);
  // A check's pose and errors are shown only when the part was found in the gripper.
  const bool found = r.grip_state == static_cast<std::uint16_t>(reg::GripState::Expected) ||
                     r.grip_state == static_cast<std::uint16_t>(reg::GripState::PoseError);
  regs[reg::kGripState] = r.grip_state;
  regs[reg::kGripOfJob] = r.grip_state != 0 ? r.grip_of_job : 0;
  put_pose(reg::kGripX, r.grip_pose, found);
  put(reg::kGripTranslationError, found ? r.grip_translation_mm : 0.0f);
  put(reg::kGripRotationError, found ? r.grip_rotation_deg : 0.0f);
  std::memcpy(map->tab_input_registers, regs, reg::kBlockSize * sizeof(std::uint16_t));
  return r;
}

void ModbusServer::Impl::send_exception(Client& c, std::uint8_t function, ModbusException code) {
  std::uint8_t rsp[9] = {c.buf[0],
                         c.buf[1],
                         0,
                         0,
                         0,
                         3,
                         c.buf[6],
                         static_cast<std::uint8_t>(function | 0x80),
                         static_cast<std::uint8_t>(code)};
  server.exceptions_.fetch_add(1);
  if (::send(c.fd.get(), rsp, sizeof(rsp), MSG_NOSIGNAL | MSG_DONTWAIT) != sizeof(rsp))
    close_client(c, CloseReason::Dropped);
}

ModbusException ModbusServer::Impl::decide_command(const RegisterWrite& w, const RobotReport& report,
                                                   std::optional<PlcCommand>& command) {
  std::uint16_t control[reg::kControlEnd];
  control_after(w, control);
  const PlcCommand asked{PlcCommand::Kind::Trigger, control[reg::kJobId], control[reg::kRecipeId], control[reg::kMode]};
  const auto command_code = static_cast<reg::Command>(control[reg::kCommand]);
  switch (command_code) {
    case reg::Command::None:
      return ModbusException::None;
    case reg::Command::Trigger:
    case reg::Command::SaveScene:
    case reg::Command::Look:
    case reg::Command::CheckGrip:
      // A new job: same checks, same handshake for all four.
      if (asked.job_id == 0 || asked.job_id == last_job || asked.mode > reg::kModeMax)
        return ModbusException::IllegalDataValue;
      if (job_pending || !report.ready || report.error_code != 0 || queue_full())
        return ModbusException::ServerDeviceBusy;
      // LOOK continues the job in the registers, and only when its result asked for a second look.
      if (command_code == reg::Command::Look && (report.job_id == 0 || !report.look_wanted))
        return ModbusException::IllegalDataValue;
      // CHECK_GRIP checks the pick in the registers: only a result that shows one (PICK_VALID).
      if (command_code == reg::Command::CheckGrip && (report.job_id == 0 || !shows_pick(report)))
        return ModbusException::IllegalDataValue;
      command = asked;
      if (command_code == reg::Command::SaveScene) command->kind = PlcCommand::Kind::SaveScene;
      if (command_code == reg::Command::Look) {
        command->kind = PlcCommand::Kind::Look;
        command->look_of_job = report.job_id;
      }
      if (command_code == reg::Command::CheckGrip) {
        command->kind = PlcCommand::Kind::CheckGrip;
        command->rank = shown_rank;
        command->check_of_job = report.job_id;
      }
      return ModbusException::None;
    case reg::Command::Reset:
      if (queue_full()) return ModbusException::ServerDeviceBusy;
      command = asked;
      command->kind = PlcCommand::Kind::Reset;
      return ModbusException::None;
    case reg::Command::Next:
      // The job in the registers: its next pick, if it has one.
      if (job_pending || report.error_code != 0 || queue_full()) return ModbusException::ServerDeviceBusy;
      if (!shows_pick(report) || report.job_id == 0 || shown_rank + 1 >= report.pick_count)
        return ModbusException::IllegalDataValue;
      command = PlcCommand{
          PlcCommand::Kind::Next, report.job_id, report.recipe_id, 0, static_cast<std::uint16_t>(shown_rank + 1), 0};
      return ModbusException::None;
  }
  return ModbusException::IllegalDataValue;
}

ModbusException ModbusServer::Impl::decide_pick_result(const RegisterWrite& w, const RobotReport& report,
                                                       std::optional<PlcCommand>& result) {
  std::uint16_t control[reg::kControlEnd];
  control_after(w, control);
  const std::uint16_t outcome = control[reg::kPickResult];
  if (outcome == static_cast<std::uint16_t>(reg::PickOutcome::None)) return ModbusException::None;
  if (outcome > reg::kPickOutcomeMax) return ModbusException::IllegalDataValue;
  // Only the pick in the registers can be reported on: the job must be JOB_ID_ECHO and have a pick.
  if (report.job_id == 0 || control[reg::kPickResultJob] != report.job_id || !shows_pick(report))
    return ModbusException::IllegalDataValue;
  if (reported_job == report.job_id && reported_rank == shown_rank) return ModbusException::None;  // a repeat
  if (queue_full()) return ModbusException::ServerDeviceBusy;
  result = PlcCommand{PlcCommand::Kind::PickResult, report.job_id, report.recipe_id, 0, shown_rank, outcome};
  return ModbusException::None;
}

void ModbusServer::Impl::control_after(const RegisterWrite& w, std::uint16_t (&control)[reg::kControlEnd]) const {
  const std::uint16_t* regs = map->tab_registers;
  std::copy(regs, regs + reg::kControlEnd, control);
  for (std::uint16_t i = 0; i < w.count && w.address + i < reg::kControlEnd; ++i)
    control[w.address + i] = be16(w.values + 2 * i);
}

bool ModbusServer::Impl::queue_full() const noexcept {
  // Room for a command and a pick result from one write.
  return server.commands_.size_approx() + 2 > server.commands_.capacity();
}

bool ModbusServer::Impl::write_robot_pose(const RegisterWrite& w) {
  const std::uint16_t* regs = map->tab_registers;
  std::uint16_t block[reg::kRobotPoseEnd - reg::kRobotPoseBegin];
  std::copy(regs + reg::kRobotPoseBegin, regs + reg::kRobotPoseEnd, block);
  for (std::uint16_t i = 0; i < w.count; ++i) block[w.address + i - reg::kRobotPoseBegin] = be16(w.values + 2 * i);
  const auto f = [&](std::uint16_t at) {
    const std::uint16_t* q = block + (at - reg::kRobotPoseBegin);
    return decode_float(q[0], q[1], config.word_order);
  };
  bool ok = block[reg::kRobotPoseValid - reg::kRobotPoseBegin] <= 1;
  for (std::uint16_t at = reg::kRobotPoseX; at < reg::kRobotPoseValid; at += 2) ok = ok && std::isfinite(f(at));
  if (!ok) return false;
  // Published before the answer: once the PLC has its acknowledgement, mfcd sees the pose.
  RobotPoseReading p = server.robot_pose_.read();
  ++p.writes;
  p.valid = block[reg::kRobotPoseValid - reg::kRobotPoseBegin];
  p.sequence = block[reg::kRobotPoseSeq - reg::kRobotPoseBegin];
  p.x_mm = f(reg::kRobotPoseX), p.y_mm = f(reg::kRobotPoseY), p.z_mm = f(reg::kRobotPoseZ);
  p.rx_deg = f(reg::kRobotPoseRx), p.ry_deg = f(reg::kRobotPoseRy), p.rz_deg = f(reg::kRobotPoseRz);
  server.robot_pose_.publish(p);
  return true;
}

void ModbusServer::Impl::queue_command(const PlcCommand& command) {
  switch (command.kind) {
    case PlcCommand::Kind::Trigger:
    case PlcCommand::Kind::SaveScene:
    case PlcCommand::Kind::Look:
    case PlcCommand::Kind::CheckGrip:
      job_pending = true;
      last_job = command.job_id;
      break;
    case PlcCommand::Kind::Reset:
      job_pending = false;
      break;
    case PlcCommand::Kind::Next:
      break;
    case PlcCommand::Kind::PickResult:
      reported_job = command.job_id;
      reported_rank = command.rank;
      break;
  }
  if (command.kind != PlcCommand::Kind::PickResult) map->tab_registers[reg::kCommand] = 0;  // reads back 0 once taken
  server.commands_.push(command);
  server.queued_.fetch_add(1);
  const std::uint64_t one = 1;
  [[maybe_unused]] ssize_t n = ::write(server.command_event_fd_.get(), &one, sizeof(one));
  refresh_registers();
}

void ModbusServer::Impl::handle_frame(Client& c, std::size_t size) {
  const RobotReport report = refresh_registers();
  c.seen = report_count;
  const GuardVerdict v = check_request(std::span<const std::uint8_t>(c.buf, size), kPolicy);
  if (v.exception != ModbusException::None) {
    send_exception(c, v.function, v.exception);
    return;
  }

  // A write covering the command register is a command, one covering PICK_RESULT a pick
  // report: both are decided on before any register changes, so a refused write leaves the
  // map untouched. In one write, the report is on the pick shown before the command.
  std::optional<PlcCommand> command, pick_result;
  const RegisterWrite& w = v.write;
  const auto covers = [&](std::uint16_t at) { return w.count > 0 && w.address <= at && at < w.address + w.count; };
  ModbusException refuse = ModbusException::None;
  if (covers(reg::kPickResult)) refuse = decide_pick_result(w, report, pick_result);
  if (covers(reg::kCommand)) {
    if (refuse == ModbusException::None) refuse = decide_command(w, report, command);
    last_command_result = static_cast<std::uint16_t>(refuse);
    map->tab_registers[reg::kLastCommandResult] = last_command_result;
  }
  if (refuse != ModbusException::None) {
    send_exception(c, v.function, refuse);
    return;
  }
  // A write into the robot pose block is checked as the block it would leave: a valid flag
  // other than 0/1 or a non-finite float is refused and nothing is written.
  if (w.count > 0 && w.address < reg::kRobotPoseEnd && w.address + w.count > reg::kRobotPoseBegin &&
      !write_robot_pose(w)) {
    send_exception(c, v.function, ModbusException::IllegalDataValue);
    return;
  }
  if (pick_result) queue_command(*pick_result);
  // NEXT is served here and now: the registers (and the read half of an FC 0x17) show the
  // next pick before the answer leaves.
  if (command && command->kind == PlcCommand::Kind::Next) {
    shown_rank = command->rank;
    refresh_registers();
  }
  modbus_set_socket(ctx, c.fd.get());
  // modbus_reply() writes the map before it sends: a command whose acknowledgement could not
  // be sent is queued all the same, as the register write it came with has happened.
  const bool replied = modbus_reply(ctx, c.buf, static_cast<int>(size), map) >= 0;
  if (replied) server.answered_.fetch_add(1);
  if (command) queue_command(*command);
  if (!replied) close_client(c, CloseReason::Dropped);
}

}  // namespace mfcd::motion
