// Map version 4 on real loopback sockets with a real libmodbus client: a result that asks for a
// second look (STATUS LOOK_WANTED, LOOK_REASON, LOOK_X..LOOK_RZ) and COMMAND 5 LOOK, the job
// that takes it (docs/register-map.md, "Second look").
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
using test::LibmodbusClient;
using test::look_pose_for_job;
using test::loopback_config;
using test::pick_for_job;
using test::RawClient;
using test::reg_float;
using test::SimulatedDaemon;
using test::wait_for_echo;

namespace {

constexpr std::uint16_t kLook = static_cast<std::uint16_t>(reg::Command::Look);
constexpr std::uint16_t kNext = static_cast<std::uint16_t>(reg::Command::Next);
constexpr std::uint16_t kMissed = static_cast<std::uint16_t>(reg::PickOutcome::Missed);
constexpr std::uint16_t kAmbiguous = static_cast<std::uint16_t>(reg::LookReason::Ambiguous);

// The flange pose of the docs/register-map.md example (the robot pose block's, too).
constexpr PickPose kDocLookPose{512.25f, -130.5f, 740.125f, 179.5f, -2.25f, 45.0f};

// A report for `job` that asks for a second look from `pose`, as the daemon publishes it.
RobotReport look_report(std::uint16_t job, std::uint16_t reason, const PickPose& pose) {
  RobotReport r;
  r.ready = 1;
  r.vision_ok = 1;
  r.job_id = job;
  r.recipe_id = 3;
  r.candidate_count = 2;
  r.look_wanted = 1;
  r.look_reason = reason;
  r.look_pose = pose;
  return r;
}

void expect_look(const std::vector<std::uint16_t>& block, std::uint16_t reason, const PickPose& pose, WordOrder order) {
  EXPECT_TRUE(block[reg::kStatus] & reg::kLookWanted);
  EXPECT_FALSE(block[reg::kStatus] & reg::kPickValid);
  EXPECT_EQ(block[reg::kLookReason], reason);
  EXPECT_EQ(reg_float(block, reg::kLookX, order), pose.x_mm);
  EXPECT_EQ(reg_float(block, reg::kLookY, order), pose.y_mm);
  EXPECT_EQ(reg_float(block, reg::kLookZ, order), pose.z_mm);
  EXPECT_EQ(reg_float(block, reg::kLookRx, order), pose.rx_deg);
  EXPECT_EQ(reg_float(block, reg::kLookRy, order), pose.ry_deg);
  EXPECT_EQ(reg_float(block, reg::kLookRz, order), pose.rz_deg);
  for (int at = reg::kPickX; at < reg::kScore + 2; ++at) EXPECT_EQ(block[at], 0) << "no pick: register " << at;
}

void expect_no_look(const std::vector<std::uint16_t>& block) {
  EXPECT_FALSE(block[reg::kStatus] & reg::kLookWanted);
  EXPECT_EQ(std::vector<std::uint16_t>(block.begin() + reg::kLookReason, block.begin() + reg::kLookRz + 2),
            std::vector<std::uint16_t>(reg::kLookRz + 2 - reg::kLookReason, 0))
      << "LOOK_REASON and LOOK_X..LOOK_RZ read 0 without LOOK_WANTED";
}

}  // namespace

TEST(ModbusMapV4, VersionAndEightyRegisterRead) {
  ModbusServer server(loopback_config());
  server.start();
  LibmodbusClient plc(server.port());
  EXPECT_GE(plc.read(reg::kMapVersionReg, 1)[0], 4) << "later versions keep every version 4 address";
  const auto block = plc.read(0, 80);
  EXPECT_EQ(block[reg::kTestVector], 0x47F1);
  expect_no_look(block);
  EXPECT_EQ(std::vector<std::uint16_t>(block.begin() + 68, block.end()), std::vector<std::uint16_t>(12, 0))
      << "68..79 read 0 (map version 5: no gripper check result)";
  EXPECT_EQ(plc.read(0, 64).size(), 64u) << "a map version 3 PLC's read of 64 still works";
  EXPECT_EQ(plc.read(79, 1), std::vector<std::uint16_t>{0});
  std::vector<std::uint16_t> input(80);
  EXPECT_EQ(modbus_read_input_registers(plc.ctx, 0, 80, input.data()), 80) << "FC 0x04 mirrors the first 80";

  EXPECT_EQ(plc.write(reg::kLookReason, {1}), EMBXILADD) << "55..67 are read-only";
  EXPECT_EQ(plc.write(reg::kLookX, {0, 0}), EMBXILADD);
  EXPECT_EQ(plc.write(68, {1}), EMBXILADD) << "read-only";
  EXPECT_EQ(plc.write(reg::kRobotPoseSeq, {1, 0}), EMBXILADD) << "the pose block still ends at 49";
}

// The daemon's report decides what 55..67 and STATUS bit 6 show; in both word orders the six
// floats decode to exactly the pose published.
TEST(ModbusMapV4, LookWantedShowsReasonAndPoseInBothWordOrders) {
  for (const WordOrder order : {WordOrder::ABCD, WordOrder::CDAB}) {
    SCOPED_TRACE(std::string(to_string(order)));
    ModbusServer server(loopback_config(order));
    server.start();
    LibmodbusClient plc(server.port());

    server.publish(look_report(12, kAmbiguous, kDocLookPose));
    auto block = plc.read(0, reg::kBlockSize);
    EXPECT_EQ(block[reg::kJobIdEcho], 12);
    EXPECT_EQ(block[reg::kStatus], reg::kReady | reg::kVisionOk | reg::kLookWanted);
    expect_look(block, kAmbiguous, kDocLookPose, order);
    if (order == WordOrder::ABCD) {  // the example in docs/register-map.md, word for word
      EXPECT_EQ(std::vector<std::uint16_t>(block.begin() + reg::kLookReason, block.begin() + reg::kLookRz + 2),
                (std::vector<std::uint16_t>{2, 0x4400, 0x1000, 0xC302, 0x8000, 0x4439, 0x0800, 0x4333, 0x8000, 0xC010,
                                            0x0000, 0x4234, 0x0000}));
    }

    const PickPose other{-1.5f, 2048.0f, 0.125f, -179.75f, 89.5f, -0.25f};
    for (const std::uint16_t reason : {1, 2, 3}) {
      server.publish(look_report(13, reason, other));
      expect_look(plc.read(0, reg::kBlockSize), reason, other, order);
    }

    // A report with look_wanted shows no pick, even one that claims pick_valid.
    RobotReport both = look_report(14, 3, other);
    both.pick_valid = 1;
    both.pick = pick_for_job(14);
    both.score = 0.5f;
    server.publish(both);
    block = plc.read(0, reg::kBlockSize);
    expect_look(block, 3, other, order);
    EXPECT_EQ(block[reg::kPickRank], 0);
    EXPECT_EQ(block[reg::kPicksLeft], 0);

    // Without look_wanted, whatever else the report holds, 55..67 read 0.
    RobotReport no_look = look_report(15, 2, other);
    no_look.look_wanted = 0;
    no_look.pick_valid = 1;
    no_look.pick = pick_for_job(15);
    server.publish(no_look);
    block = plc.read(0, reg::kBlockSize);
    expect_no_look(block);
    EXPECT_TRUE(block[reg::kStatus] & reg::kPickValid);
    EXPECT_EQ(reg_float(block, reg::kPickX, order), pick_for_job(15).x_mm);
  }
}

// TRIGGER → DONE with LOOK_WANTED → LOOK with a new job id → DONE with the pick, with the
// simulated daemon behind the server (recipe 92: a second look for reason 2, ambiguous).
TEST(ModbusMapV4, LookStartsAJobThatContinuesTheFirstLook) {
  ModbusServer server(loopback_config());
  server.start();
  SimulatedDaemon daemon(server, 100ms);
  LibmodbusClient plc(server.port());

  EXPECT_EQ(plc.write(reg::kCommand, {kLook, 69, 92, 0}), EMBXILVAL) << "no result yet";
  ASSERT_EQ(plc.write(reg::kCommand, {1, 70, 92, 0}), 0);
  auto block = wait_for_echo(plc, 70);
  EXPECT_TRUE(block[reg::kStatus] & reg::kDone);
  expect_look(block, kAmbiguous, look_pose_for_job(70), WordOrder::ABCD);
  // A result asking for a second look has no pick: NEXT and PICK_RESULT as on a result without one.
  EXPECT_EQ(plc.write(reg::kCommand, {kNext}), EMBXILVAL);
  EXPECT_EQ(plc.write(reg::kPickResult, {kMissed, 70}), EMBXILVAL);
  EXPECT_EQ(plc.write(reg::kCommand, {kLook, 70, 92, 0}), EMBXILVAL) << "LOOK needs a new job id, as TRIGGER";
  EXPECT_EQ(plc.write(reg::kCommand, {kLook, 0, 92, 0}), EMBXILVAL) << "job id 0";
  EXPECT_EQ(plc.write(reg::kCommand, {kLook, 71, 92, 9}), EMBXILVAL) << "mode 9";

  ASSERT_EQ(plc.write(reg::kCommand, {kLook, 71, 92, 0}), 0);
  block = plc.read(0, reg::kBlockSize);
  EXPECT_EQ(block[reg::kCommand], 0) << "reads back 0 once taken";
  EXPECT_EQ(block[reg::kLastCommandResult], 0);
  EXPECT_TRUE(block[reg::kStatus] & reg::kBusy);
  EXPECT_FALSE(block[reg::kStatus] & reg::kReady);
  EXPECT_FALSE(block[reg::kStatus] & reg::kDone);
  EXPECT_EQ(block[reg::kJobIdEcho], 70) << "the registers still hold job 70's result";
  expect_look(block, kAmbiguous, look_pose_for_job(70), WordOrder::ABCD);
  EXPECT_TRUE(eventually([&] { return daemon.looks.load() == 1; }));
  EXPECT_EQ(daemon.look_job.load(), 71);
  EXPECT_EQ(daemon.look_of_job.load(), 70);
  EXPECT_EQ(daemon.last_recipe.load(), 92);
  EXPECT_EQ(daemon.last_mode.load(), 0);

  block = wait_for_echo(plc, 71);
  EXPECT_TRUE(block[reg::kStatus] & reg::kDone);
  EXPECT_TRUE(block[reg::kStatus] & reg::kPickValid);
  EXPECT_FALSE(block[reg::kStatus] & reg::kBusy);
  expect_no_look(block);
  EXPECT_EQ(reg_float(block, reg::kPickX, WordOrder::ABCD), pick_for_job(71).x_mm);
  EXPECT_EQ(reg_float(block, reg::kPickRz, WordOrder::ABCD), pick_for_job(71).rz_deg);

  // The fused result asks for nothing more: LOOK is refused and nothing changes.
  EXPECT_EQ(plc.write(reg::kCommand, {kLook, 72, 92, 0}), EMBXILVAL);
  block = plc.read(0, reg::kBlockSize);
  EXPECT_EQ(block[reg::kLastCommandResult], 3);
  EXPECT_EQ(block[reg::kJobId], 71) << "a refused write changes nothing";
  EXPECT_FALSE(block[reg::kStatus] & reg::kBusy);
  EXPECT_TRUE(block[reg::kStatus] & reg::kDone);
  std::this_thread::sleep_for(50ms);
  EXPECT_EQ(daemon.looks.load(), 1) << "nothing reached the daemon";

  // Recipe and mode reach the daemon as written (recipe 91: reason 1, COUNT_ONLY).
  ASSERT_EQ(plc.write(reg::kCommand, {1, 73, 91, 0}), 0);
  expect_look(wait_for_echo(plc, 73), 1, look_pose_for_job(73), WordOrder::ABCD);
  ASSERT_EQ(plc.write(reg::kCommand, {kLook, 74, 91, 1}), 0);
  block = wait_for_echo(plc, 74);
  EXPECT_EQ(daemon.looks.load(), 2);
  EXPECT_EQ(daemon.look_of_job.load(), 73);
  EXPECT_EQ(daemon.last_recipe.load(), 91);
  EXPECT_EQ(daemon.last_mode.load(), 1);
  EXPECT_FALSE(block[reg::kStatus] & reg::kPickValid) << "COUNT_ONLY";
  EXPECT_EQ(daemon.triggers.load(), 2);
  EXPECT_EQ(server.stats().commands_queued, 4u);
}

TEST(ModbusMapV4, LookRefusedWhileBusyOrInError) {
  ModbusServer server(loopback_config());
  server.start();
  SimulatedDaemon daemon(server, 300ms);
  LibmodbusClient plc(server.port());
  ASSERT_EQ(plc.write(reg::kCommand, {1, 80, 93, 0}), 0);
  EXPECT_EQ(plc.write(reg::kCommand, {kLook, 81, 93, 0}), EMBXSBUSY) << "job 80 still running";
  expect_look(wait_for_echo(plc, 80), 3, look_pose_for_job(80), WordOrder::ABCD);
  ASSERT_EQ(plc.write(reg::kCommand, {kLook, 81, 93, 0}), 0);
  EXPECT_EQ(plc.write(reg::kCommand, {kLook, 82, 93, 0}), EMBXSBUSY) << "the LOOK job 81 is running";
  EXPECT_EQ(plc.read(reg::kLastCommandResult, 1)[0], 6);
  EXPECT_EQ(plc.read(reg::kJobId, 1)[0], 81) << "a refused write changes nothing";
  wait_for_echo(plc, 81);

  // An error latched on a result that asked for a second look: busy until RESET, as TRIGGER.
  ASSERT_EQ(plc.write(reg::kCommand, {1, 83, 93, 0}), 0);
  wait_for_echo(plc, 83);
  daemon.fail_next = true;
  ASSERT_EQ(plc.write(reg::kCommand, {kLook, 84, 93, 0}), 0);
  auto block = wait_for_echo(plc, 84);
  EXPECT_TRUE(block[reg::kStatus] & reg::kError);
  EXPECT_EQ(plc.write(reg::kCommand, {kLook, 85, 93, 0}), EMBXSBUSY) << "an error is latched";
  EXPECT_EQ(plc.read(reg::kLastCommandResult, 1)[0], 6);
  EXPECT_EQ(daemon.looks.load(), 2);
  EXPECT_EQ(daemon.triggers.load(), 2);
}

// docs/register-map.md, "Second look": the LOOK write exactly as the doc shows it on the wire,
// with the command as the daemon receives it, and the answers to the refused ones.
TEST(ModbusMapV4, LookOnTheWireAsTheDocShowsIt) {
  ModbusServer server(loopback_config());
  server.start();
  server.publish(look_report(21, kAmbiguous, kDocLookPose));
  RawClient raw(server.port());
  const std::vector<std::uint8_t> look_22{0x00, 0x04, 0x00, 0x00, 0x00, 0x0F, 0xFF, 0x10, 0x00, 0x00, 0x00,
                                          0x04, 0x08, 0x00, 0x05, 0x00, 0x16, 0x00, 0x03, 0x00, 0x00};
  raw.send(look_22);
  auto rsp = raw.receive(12);
  ASSERT_TRUE(rsp);
  EXPECT_EQ(*rsp, (std::vector<std::uint8_t>{0x00, 0x04, 0x00, 0x00, 0x00, 0x06, 0xFF, 0x10, 0x00, 0x00, 0x00, 0x04}));
  // The server queues the command right after its answer leaves: wait for the daemon's wake-up.
  pollfd wake{server.command_fd(), POLLIN, 0};
  ASSERT_EQ(::poll(&wake, 1, 2000), 1);
  const auto cmd = server.next_command();
  ASSERT_TRUE(cmd);
  EXPECT_EQ(cmd->kind, PlcCommand::Kind::Look);
  EXPECT_EQ(cmd->job_id, 22);
  EXPECT_EQ(cmd->recipe_id, 3);
  EXPECT_EQ(cmd->mode, 0);
  EXPECT_EQ(cmd->look_of_job, 21);
  EXPECT_EQ(cmd->rank, 0);
  EXPECT_FALSE(server.next_command());

  LibmodbusClient plc(server.port());
  EXPECT_EQ(plc.read(reg::kStatus, 2),
            (std::vector<std::uint16_t>{reg::kBusy | reg::kVisionOk | reg::kLookWanted, 21}));
  // Busy: the same bytes with job 23.
  std::vector<std::uint8_t> look_23 = look_22;
  look_23[16] = 0x17;
  raw.send(look_23);
  rsp = raw.receive(9);
  ASSERT_TRUE(rsp);
  EXPECT_EQ(*rsp, (std::vector<std::uint8_t>{0x00, 0x04, 0x00, 0x00, 0x00, 0x03, 0xFF, 0x90, 0x06}));

  // Job 22's fused result, with its pick and no second look wanted: LOOK is refused with 0x03.
  RobotReport fused;
  fused.ready = 1;
  fused.vision_ok = 1;
  fused.job_id = 22;
  fused.recipe_id = 3;
  fused.pick_valid = 1;
  fused.pick = pick_for_job(22);
  server.publish(fused);
  raw.send(look_23);
  rsp = raw.receive(9);
  ASSERT_TRUE(rsp);
  EXPECT_EQ(*rsp, (std::vector<std::uint8_t>{0x00, 0x04, 0x00, 0x00, 0x00, 0x03, 0xFF, 0x90, 0x03}));
  EXPECT_FALSE(server.next_command()) << "nothing reaches the daemon";
  const auto block = plc.read(0, reg::kBlockSize);
  EXPECT_EQ(block[reg::kLastCommandResult], 3);
  EXPECT_EQ(block[reg::kStatus], reg::kReady | reg::kDone | reg::kPickValid | reg::kVisionOk);
  EXPECT_EQ(block[reg::kJobId], 22);
}
