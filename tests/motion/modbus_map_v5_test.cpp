// Map version 5 on real loopback sockets with a real libmodbus client: COMMAND 6 CHECK_GRIP, the
// job that checks the part in the gripper after the robot took the pick in the registers, and
// its result in GRIP_STATE, GRIP_OF_JOB and GRIP_X..GRIP_ROTATION_ERROR (68..85)
// (docs/register-map.md, "Gripper check").
#include "modbus_test_util.hpp"
#include "motion/modbus_server.hpp"
#include "motion/register_map.hpp"
#include "sim_daemon.hpp"

#include <gtest/gtest.h>

#include <modbus/modbus.h>
#include <poll.h>

#include <cerrno>
#include <chrono>
#include <string>
#include <thread>
#include <vector>

using namespace mfcd::motion;
using namespace std::chrono_literals;
using test::eventually;
using test::grip_pose_for_job;
using test::kSimGripRecipe;
using test::LibmodbusClient;
using test::loopback_config;
using test::pick_for_job;
using test::RawClient;
using test::reg_float;
using test::SimulatedDaemon;
using test::wait_for_echo;

namespace {

constexpr std::uint16_t kCheckGrip = static_cast<std::uint16_t>(reg::Command::CheckGrip);
constexpr std::uint16_t kNext = static_cast<std::uint16_t>(reg::Command::Next);
constexpr std::uint16_t kOk = static_cast<std::uint16_t>(reg::PickOutcome::Ok);
constexpr std::uint16_t kMissed = static_cast<std::uint16_t>(reg::PickOutcome::Missed);
constexpr auto kExpected = reg::GripState::Expected;
constexpr auto kPoseError = reg::GripState::PoseError;
constexpr auto kNotGrasped = reg::GripState::NotGrasped;

// The docs/register-map.md example: the part 2.0 mm off in x, -1.5 mm in y and turned 6.5 degrees
// about the tool's z axis from the ideal tool_T_part (0, 0, 148) mm, (0, 0, 0) degrees.
constexpr PickPose kDocGripPose{2.0f, -1.5f, 148.0f, 0.0f, 0.0f, 6.5f};
constexpr float kDocTranslationError = 2.5f, kDocRotationError = 6.5f;

// A result for `job` with a pick, as the daemon publishes a TRIGGER's.
RobotReport pick_report(std::uint16_t job) {
  RobotReport r;
  r.ready = 1;
  r.vision_ok = 1;
  r.job_id = job;
  r.recipe_id = 3;
  r.candidate_count = 5;
  r.pick_valid = 1;
  r.pick = pick_for_job(job);
  r.score = 0.875f;
  return r;
}

// The result of the CHECK_GRIP job `job` on the pick of job `of_job`.
RobotReport grip_report(std::uint16_t job, std::uint16_t of_job, reg::GripState state, const PickPose& pose,
                        float translation_mm, float rotation_deg) {
  RobotReport r;
  r.ready = 1;
  r.vision_ok = 1;
  r.job_id = job;
  r.recipe_id = 3;
  r.grip_state = static_cast<std::uint16_t>(state);
  r.grip_of_job = of_job;
  r.grip_pose = pose;
  r.grip_translation_mm = translation_mm;
  r.grip_rotation_deg = rotation_deg;
  return r;
}

std::vector<std::uint16_t> grip_block(const std::vector<std::uint16_t>& block) {
  return {block.begin() + reg::kGripState, block.begin() + reg::kGripRotationError + 2};
}

// 68..85 as a result of `state` on the pick of `of_job` shows them; pose and errors only when
// the part was found in the gripper.
void expect_grip(const std::vector<std::uint16_t>& block, reg::GripState state, std::uint16_t of_job,
                 const PickPose& pose, float translation_mm, float rotation_deg, WordOrder order) {
  EXPECT_EQ(block[reg::kGripState], static_cast<std::uint16_t>(state));
  EXPECT_EQ(block[reg::kGripOfJob], of_job);
  const bool found = state == kExpected || state == kPoseError;
  EXPECT_EQ(reg_float(block, reg::kGripX, order), found ? pose.x_mm : 0.0f);
  EXPECT_EQ(reg_float(block, reg::kGripY, order), found ? pose.y_mm : 0.0f);
  EXPECT_EQ(reg_float(block, reg::kGripZ, order), found ? pose.z_mm : 0.0f);
  EXPECT_EQ(reg_float(block, reg::kGripRx, order), found ? pose.rx_deg : 0.0f);
  EXPECT_EQ(reg_float(block, reg::kGripRy, order), found ? pose.ry_deg : 0.0f);
  EXPECT_EQ(reg_float(block, reg::kGripRz, order), found ? pose.rz_deg : 0.0f);
  EXPECT_EQ(reg_float(block, reg::kGripTranslationError, order), found ? translation_mm : 0.0f);
  EXPECT_EQ(reg_float(block, reg::kGripRotationError, order), found ? rotation_deg : 0.0f);
  // A check's result has no pick.
  EXPECT_FALSE(block[reg::kStatus] & reg::kPickValid);
  for (int at = reg::kPickX; at < reg::kScore + 2; ++at) EXPECT_EQ(block[at], 0) << "no pick: register " << at;
  EXPECT_EQ(block[reg::kPickRank], 0);
  EXPECT_EQ(block[reg::kPicksLeft], 0);
}

void expect_no_grip(const std::vector<std::uint16_t>& block) {
  EXPECT_EQ(grip_block(block), std::vector<std::uint16_t>(reg::kGripRotationError + 2 - reg::kGripState, 0))
      << "68..85 read 0 in a result that is not a gripper check";
}

}  // namespace

TEST(ModbusMapV5, VersionAndNinetySixRegisterBlock) {
  ModbusServer server(loopback_config());
  server.start();
  LibmodbusClient plc(server.port());
  EXPECT_EQ(reg::kBlockSize, 96);
  EXPECT_EQ(plc.read(reg::kMapVersionReg, 1)[0], 5);
  const auto block = plc.read(0, 96);
  EXPECT_EQ(block[reg::kMapVersionReg], 5);
  EXPECT_EQ(block[reg::kTestVector], 0x47F1);
  expect_no_grip(block);
  EXPECT_EQ(std::vector<std::uint16_t>(block.begin() + 86, block.end()), std::vector<std::uint16_t>(10, 0))
      << "86..95 reserved";
  EXPECT_EQ(plc.read(0, 80).size(), 80u) << "a map version 4 PLC's read of 80 still works";
  EXPECT_EQ(plc.read(0, 64).size(), 64u) << "a map version 3 PLC's read of 64 still works";
  EXPECT_EQ(plc.read(95, 1), std::vector<std::uint16_t>{0});
  std::vector<std::uint16_t> input(96);
  EXPECT_EQ(modbus_read_input_registers(plc.ctx, 0, 96, input.data()), 96) << "FC 0x04 mirrors all 96";

  std::uint16_t two[2];
  EXPECT_EQ(modbus_read_registers(plc.ctx, 95, 2, two), -1);
  EXPECT_EQ(errno, EMBXILADD) << "a read reaching past 95";
  EXPECT_EQ(modbus_read_registers(plc.ctx, 96, 1, two), -1);
  EXPECT_EQ(errno, EMBXILADD);
  EXPECT_EQ(modbus_read_input_registers(plc.ctx, 95, 2, two), -1);
  EXPECT_EQ(errno, EMBXILADD);
  EXPECT_EQ(plc.write(reg::kGripState, {1}), EMBXILADD) << "68..85 are read-only";
  EXPECT_EQ(plc.write(reg::kGripOfJob, {1}), EMBXILADD);
  EXPECT_EQ(plc.write(reg::kGripX, {0, 0}), EMBXILADD);
  EXPECT_EQ(plc.write(reg::kGripRotationError, {0, 0}), EMBXILADD);
  for (const int at : {86, 90, 95}) EXPECT_EQ(plc.write(at, {1}), EMBXILADD) << "reserved " << at;
  EXPECT_EQ(plc.write(86, std::vector<std::uint16_t>(10, 0)), EMBXILADD) << "reserved 86..95";
  EXPECT_EQ(plc.read(reg::kGripState, 28), std::vector<std::uint16_t>(28, 0)) << "refused writes change nothing";
}

// The daemon's report decides what 68..85 show; in both word orders the eight floats decode to
// exactly the values published.
TEST(ModbusMapV5, GripResultShowsInBothWordOrders) {
  for (const WordOrder order : {WordOrder::ABCD, WordOrder::CDAB}) {
    SCOPED_TRACE(std::string(to_string(order)));
    ModbusServer server(loopback_config(order));
    server.start();
    LibmodbusClient plc(server.port());

    server.publish(grip_report(23, 22, kPoseError, kDocGripPose, kDocTranslationError, kDocRotationError));
    auto block = plc.read(0, reg::kBlockSize);
    EXPECT_EQ(block[reg::kJobIdEcho], 23);
    EXPECT_EQ(block[reg::kStatus], reg::kReady | reg::kVisionOk);
    expect_grip(block, kPoseError, 22, kDocGripPose, kDocTranslationError, kDocRotationError, order);
    if (order == WordOrder::ABCD) {  // the example in docs/register-map.md, word for word
      EXPECT_EQ(grip_block(block),
                (std::vector<std::uint16_t>{2, 22, 0x4000, 0x0000, 0xBFC0, 0x0000, 0x4314, 0x0000, 0x0000, 0x0000,
                                            0x0000, 0x0000, 0x40D0, 0x0000, 0x4020, 0x0000, 0x40D0, 0x0000}));
    }

    const PickPose other{-0.125f, 3.5f, 151.75f, -179.5f, 1.25f, -90.5f};
    for (const auto state : {kExpected, kPoseError, kNotGrasped}) {
      server.publish(grip_report(24, 21, state, other, 0.75f, 1.5f));
      expect_grip(plc.read(0, reg::kBlockSize), state, 21, other, 0.75f, 1.5f, order);
    }

    // A check's result shows no pick, even one that claims pick_valid.
    RobotReport both = grip_report(25, 21, kExpected, other, 0.75f, 1.5f);
    both.pick_valid = 1;
    both.pick = pick_for_job(25);
    both.score = 0.5f;
    server.publish(both);
    expect_grip(plc.read(0, reg::kBlockSize), kExpected, 21, other, 0.75f, 1.5f, order);

    // With grip_state 0, whatever else the report holds, 68..85 read 0.
    RobotReport no_grip = grip_report(26, 21, reg::GripState::None, other, 0.75f, 1.5f);
    no_grip.pick_valid = 1;
    no_grip.pick = pick_for_job(26);
    server.publish(no_grip);
    block = plc.read(0, reg::kBlockSize);
    expect_no_grip(block);
    EXPECT_TRUE(block[reg::kStatus] & reg::kPickValid);
    EXPECT_EQ(reg_float(block, reg::kPickX, order), pick_for_job(26).x_mm);
  }
}

// TRIGGER → the pick (NEXT to rank 1) → CHECK_GRIP with a new job id → DONE with the grip result,
// with the simulated daemon behind the server (recipe 82: PoseError).
TEST(ModbusMapV5, CheckGripChecksThePickInTheRegisters) {
  ModbusServer server(loopback_config());
  server.start();
  SimulatedDaemon daemon(server, 100ms);
  LibmodbusClient plc(server.port());
  constexpr std::uint16_t kPoseErrorRecipe = kSimGripRecipe + 2;

  ASSERT_EQ(plc.write(reg::kCommand, {1, 30, kPoseErrorRecipe, 0}), 0);
  auto block = wait_for_echo(plc, 30);
  ASSERT_TRUE(block[reg::kStatus] & reg::kPickValid);
  expect_no_grip(block);
  ASSERT_EQ(plc.write(reg::kCommand, {kNext}), 0);
  ASSERT_EQ(plc.read(reg::kPickRank, 1)[0], 1);
  EXPECT_EQ(plc.write(reg::kCommand, {kCheckGrip, 30, kPoseErrorRecipe, 0}), EMBXILVAL)
      << "CHECK_GRIP needs a new job id, as TRIGGER";
  EXPECT_EQ(plc.write(reg::kCommand, {kCheckGrip, 0, kPoseErrorRecipe, 0}), EMBXILVAL) << "job id 0";
  EXPECT_EQ(plc.write(reg::kCommand, {kCheckGrip, 31, kPoseErrorRecipe, 9}), EMBXILVAL) << "mode 9";
  EXPECT_EQ(plc.read(reg::kLastCommandResult, 1)[0], 3);

  ASSERT_EQ(plc.write(reg::kCommand, {kCheckGrip, 31, kPoseErrorRecipe, 0}), 0);
  block = plc.read(0, reg::kBlockSize);
  EXPECT_EQ(block[reg::kCommand], 0) << "reads back 0 once taken";
  EXPECT_EQ(block[reg::kLastCommandResult], 0);
  EXPECT_TRUE(block[reg::kStatus] & reg::kBusy);
  EXPECT_FALSE(block[reg::kStatus] & reg::kReady);
  EXPECT_FALSE(block[reg::kStatus] & reg::kDone);
  EXPECT_EQ(block[reg::kJobIdEcho], 30) << "the registers still hold job 30's pick";
  EXPECT_TRUE(block[reg::kStatus] & reg::kPickValid);
  EXPECT_EQ(block[reg::kPickRank], 1);
  EXPECT_TRUE(eventually([&] { return daemon.checks.load() == 1; }));
  EXPECT_EQ(daemon.check_job.load(), 31);
  EXPECT_EQ(daemon.check_of_job.load(), 30);
  EXPECT_EQ(daemon.check_rank.load(), 1) << "PICK_RANK when CHECK_GRIP was taken";
  EXPECT_EQ(daemon.last_recipe.load(), kPoseErrorRecipe);
  EXPECT_EQ(daemon.last_mode.load(), 0);

  block = wait_for_echo(plc, 31);
  EXPECT_TRUE(block[reg::kStatus] & reg::kDone);
  EXPECT_FALSE(block[reg::kStatus] & reg::kBusy);
  EXPECT_FALSE(block[reg::kStatus] & reg::kLookWanted);
  expect_grip(block, kPoseError, 30, grip_pose_for_job(30), 6.25f, 4.5f, WordOrder::ABCD);

  // The check's result has no pick: NEXT, PICK_RESULT and another CHECK_GRIP are refused.
  EXPECT_EQ(plc.write(reg::kCommand, {kNext}), EMBXILVAL);
  EXPECT_EQ(plc.write(reg::kPickResult, {kMissed, 31}), EMBXILVAL);
  EXPECT_EQ(plc.write(reg::kPickResult, {kMissed, 30}), EMBXILVAL) << "job 30 is no longer in the registers";
  EXPECT_EQ(plc.write(reg::kCommand, {kCheckGrip, 32, kPoseErrorRecipe, 0}), EMBXILVAL);
  block = plc.read(0, reg::kBlockSize);
  EXPECT_EQ(block[reg::kLastCommandResult], 3);
  EXPECT_EQ(block[reg::kJobId], 31) << "a refused write changes nothing";
  EXPECT_TRUE(block[reg::kStatus] & reg::kDone);
  std::this_thread::sleep_for(50ms);
  EXPECT_EQ(daemon.checks.load(), 1) << "nothing reached the daemon";
  EXPECT_EQ(daemon.pick_results.load(), 0);

  // PICK_RESULT and CHECK_GRIP in one write: the report on the pick in the registers, then the
  // check of that pick (any recipe but 82 and 83: Expected; 83: NotGrasped).
  ASSERT_EQ(plc.write(reg::kCommand, {1, 33, 3, 0}), 0);
  block = wait_for_echo(plc, 33);
  expect_no_grip(block);
  ASSERT_EQ(plc.write(reg::kCommand, {kCheckGrip, 34, 3, 0, kOk, 33}), 0);
  block = wait_for_echo(plc, 34);
  expect_grip(block, kExpected, 33, grip_pose_for_job(33), 0.5f, 0.25f, WordOrder::ABCD);
  EXPECT_EQ(daemon.pick_results.load(), 1);
  EXPECT_EQ(daemon.result_job.load(), 33);
  EXPECT_EQ(daemon.result_outcome.load(), kOk);
  EXPECT_EQ(daemon.order.load() & 15u, 2u * 4 + 3) << "the pick result reached the daemon before the check";
  EXPECT_EQ(daemon.check_of_job.load(), 33);
  EXPECT_EQ(daemon.check_rank.load(), 0);

  ASSERT_EQ(plc.write(reg::kCommand, {1, 35, 3, 0}), 0);
  wait_for_echo(plc, 35);
  ASSERT_EQ(plc.write(reg::kCommand, {kCheckGrip, 36, kSimGripRecipe + 3, 0}), 0);
  expect_grip(wait_for_echo(plc, 36), kNotGrasped, 35, {}, 0, 0, WordOrder::ABCD);
  // NotGrasped: back to the bin, TRIGGER again; its result clears 68..85.
  ASSERT_EQ(plc.write(reg::kCommand, {1, 37, 3, 0}), 0);
  block = wait_for_echo(plc, 37);
  expect_no_grip(block);
  EXPECT_TRUE(block[reg::kStatus] & reg::kPickValid);
  EXPECT_EQ(daemon.checks.load(), 3);
  EXPECT_EQ(daemon.triggers.load(), 4);
  EXPECT_EQ(server.stats().commands_queued, 9u) << "4 TRIGGER, 3 CHECK_GRIP, NEXT, PICK_RESULT";
}

TEST(ModbusMapV5, CheckGripRefusedWithoutAPickWhileBusyOrInError) {
  ModbusServer server(loopback_config());
  server.start();
  SimulatedDaemon daemon(server, 300ms);
  LibmodbusClient plc(server.port());

  EXPECT_EQ(plc.write(reg::kCommand, {kCheckGrip, 40, 3, 0}), EMBXILVAL) << "no result yet";
  EXPECT_EQ(plc.read(reg::kLastCommandResult, 1)[0], 3);
  ASSERT_EQ(plc.write(reg::kCommand, {1, 41, 3, 1}), 0);
  EXPECT_EQ(plc.write(reg::kCommand, {kCheckGrip, 42, 3, 0}), EMBXSBUSY) << "job 41 still running";
  EXPECT_EQ(plc.read(reg::kLastCommandResult, 1)[0], 6);
  EXPECT_EQ(plc.read(reg::kJobId, 1)[0], 41) << "a refused write changes nothing";
  EXPECT_FALSE(wait_for_echo(plc, 41)[reg::kStatus] & reg::kPickValid) << "COUNT_ONLY";
  EXPECT_EQ(plc.write(reg::kCommand, {kCheckGrip, 42, 3, 0}), EMBXILVAL) << "a result without a pick";
  // A result that asks for a second look has no pick either.
  ASSERT_EQ(plc.write(reg::kCommand, {1, 43, test::kSimLookRecipe + 2, 0}), 0);
  EXPECT_TRUE(wait_for_echo(plc, 43)[reg::kStatus] & reg::kLookWanted);
  EXPECT_EQ(plc.write(reg::kCommand, {kCheckGrip, 44, 3, 0}), EMBXILVAL) << "LOOK_WANTED, no pick";

  ASSERT_EQ(plc.write(reg::kCommand, {1, 45, 3, 0}), 0);
  wait_for_echo(plc, 45);
  ASSERT_EQ(plc.write(reg::kCommand, {kCheckGrip, 46, 3, 0}), 0);
  EXPECT_EQ(plc.write(reg::kCommand, {kCheckGrip, 47, 3, 0}), EMBXSBUSY) << "the check job 46 is running";
  EXPECT_EQ(plc.write(reg::kCommand, {1, 47, 3, 0}), EMBXSBUSY) << "as any job";
  EXPECT_EQ(plc.read(reg::kLastCommandResult, 1)[0], 6);
  wait_for_echo(plc, 46);

  // An error latched on a result with a pick: busy until RESET, as TRIGGER.
  ASSERT_EQ(plc.write(reg::kCommand, {1, 48, 3, 0}), 0);
  wait_for_echo(plc, 48);
  daemon.fail_next = true;
  ASSERT_EQ(plc.write(reg::kCommand, {kCheckGrip, 49, 3, 0}), 0);
  auto block = wait_for_echo(plc, 49);
  EXPECT_TRUE(block[reg::kStatus] & reg::kError);
  expect_no_grip(block);
  EXPECT_EQ(plc.write(reg::kCommand, {kCheckGrip, 50, 3, 0}), EMBXSBUSY) << "an error is latched";
  EXPECT_EQ(plc.read(reg::kLastCommandResult, 1)[0], 6);
  EXPECT_EQ(daemon.checks.load(), 2);
  EXPECT_EQ(daemon.triggers.load(), 4);
}

// docs/register-map.md, "Gripper check": the CHECK_GRIP write exactly as the doc shows it on the
// wire, with the command as the daemon receives it, the answers to the refused ones, and the
// check's result as the doc shows it.
TEST(ModbusMapV5, CheckGripOnTheWireAsTheDocShowsIt) {
  ModbusServer server(loopback_config());
  server.start();
  RobotReport picked = pick_report(22);
  picked.pick_rank = 1;  // the robot took the first fall-back (NEXT once)
  picked.pick_count = 3;
  for (std::uint16_t k = 0; k < picked.pick_count; ++k) picked.ranked[k] = test::ranked_pick(22, k);
  server.publish(picked);
  RawClient raw(server.port());
  const std::vector<std::uint8_t> check_23{0x00, 0x05, 0x00, 0x00, 0x00, 0x0F, 0xFF, 0x10, 0x00, 0x00, 0x00,
                                           0x04, 0x08, 0x00, 0x06, 0x00, 0x17, 0x00, 0x03, 0x00, 0x00};
  raw.send(check_23);
  auto rsp = raw.receive(12);
  ASSERT_TRUE(rsp);
  EXPECT_EQ(*rsp, (std::vector<std::uint8_t>{0x00, 0x05, 0x00, 0x00, 0x00, 0x06, 0xFF, 0x10, 0x00, 0x00, 0x00, 0x04}));
  // The server queues the command right after its answer leaves: wait for the daemon's wake-up.
  pollfd wake{server.command_fd(), POLLIN, 0};
  ASSERT_EQ(::poll(&wake, 1, 2000), 1);
  const auto cmd = server.next_command();
  ASSERT_TRUE(cmd);
  EXPECT_EQ(cmd->kind, PlcCommand::Kind::CheckGrip);
  EXPECT_EQ(cmd->job_id, 23);
  EXPECT_EQ(cmd->recipe_id, 3);
  EXPECT_EQ(cmd->mode, 0);
  EXPECT_EQ(cmd->check_of_job, 22);
  EXPECT_EQ(cmd->rank, 1) << "PICK_RANK when CHECK_GRIP was taken";
  EXPECT_EQ(cmd->look_of_job, 0);
  EXPECT_FALSE(server.next_command());

  LibmodbusClient plc(server.port());
  EXPECT_EQ(plc.read(reg::kStatus, 2), (std::vector<std::uint16_t>{reg::kBusy | reg::kPickValid | reg::kVisionOk, 22}));
  // Busy: the same bytes with job 24.
  std::vector<std::uint8_t> check_24 = check_23;
  check_24[16] = 0x18;
  raw.send(check_24);
  rsp = raw.receive(9);
  ASSERT_TRUE(rsp);
  EXPECT_EQ(*rsp, (std::vector<std::uint8_t>{0x00, 0x05, 0x00, 0x00, 0x00, 0x03, 0xFF, 0x90, 0x06}));

  // Job 23's result, the part off its ideal pose in the gripper: the doc's 18 registers at 68.
  server.publish(grip_report(23, 22, kPoseError, kDocGripPose, kDocTranslationError, kDocRotationError));
  EXPECT_EQ(plc.read(reg::kGripState, 18),
            (std::vector<std::uint16_t>{2, 22, 0x4000, 0x0000, 0xBFC0, 0x0000, 0x4314, 0x0000, 0x0000, 0x0000, 0x0000,
                                        0x0000, 0x40D0, 0x0000, 0x4020, 0x0000, 0x40D0, 0x0000}));
  // The registers now hold the check's result, which has no pick: CHECK_GRIP is refused with 0x03.
  raw.send(check_24);
  rsp = raw.receive(9);
  ASSERT_TRUE(rsp);
  EXPECT_EQ(*rsp, (std::vector<std::uint8_t>{0x00, 0x05, 0x00, 0x00, 0x00, 0x03, 0xFF, 0x90, 0x03}));
  EXPECT_FALSE(server.next_command()) << "nothing reaches the daemon";
  const auto block = plc.read(0, reg::kBlockSize);
  EXPECT_EQ(block[reg::kLastCommandResult], 3);
  EXPECT_EQ(block[reg::kStatus], reg::kReady | reg::kDone | reg::kVisionOk);
  EXPECT_EQ(block[reg::kJobId], 23);
}
