// Map version 3 on real loopback sockets with a real libmodbus client: NEXT walks a job's
// ranked picks, PICK_RESULT reports what the robot made of one, SAVE_SCENE is a job whose
// frame set is also saved (docs/register-map.md).
#include "modbus_test_util.hpp"
#include "motion/modbus_server.hpp"
#include "motion/register_map.hpp"
#include "sim_daemon.hpp"

#include <gtest/gtest.h>
#include <modbus/modbus.h>

#include <chrono>
#include <thread>

using namespace mfcd::motion;
using namespace std::chrono_literals;
using test::eventually;
using test::LibmodbusClient;
using test::loopback_config;
using test::ranked_pick;
using test::reg_float;
using test::SimulatedDaemon;
using test::wait_for_echo;

namespace {

constexpr std::uint16_t kNext = static_cast<std::uint16_t>(reg::Command::Next);
constexpr std::uint16_t kSaveScene = static_cast<std::uint16_t>(reg::Command::SaveScene);
constexpr std::uint16_t kMissed = static_cast<std::uint16_t>(reg::PickOutcome::Missed);
constexpr std::uint16_t kUnreachable = static_cast<std::uint16_t>(reg::PickOutcome::Unreachable);
constexpr std::uint16_t kOk = static_cast<std::uint16_t>(reg::PickOutcome::Ok);

// The pick registers hold rank `rank` of `job`'s list.
void expect_pick(const std::vector<std::uint16_t>& block, std::uint16_t job, std::uint16_t rank) {
  const RankedPick want = ranked_pick(job, rank);
  EXPECT_EQ(block[reg::kJobIdEcho], job);
  EXPECT_EQ(block[reg::kPickRank], rank);
  EXPECT_EQ(block[reg::kPicksLeft], test::kSimPicksPerJob - rank - 1);
  EXPECT_EQ(block[reg::kCandidateIndex], want.candidate_index);
  EXPECT_EQ(reg_float(block, reg::kPickX, WordOrder::ABCD), want.pick.x_mm);
  EXPECT_EQ(reg_float(block, reg::kPickY, WordOrder::ABCD), want.pick.y_mm);
  EXPECT_EQ(reg_float(block, reg::kScore, WordOrder::ABCD), want.score);
  EXPECT_TRUE(block[reg::kStatus] & reg::kDone);
  EXPECT_TRUE(block[reg::kStatus] & reg::kPickValid);
}

}  // namespace

TEST(ModbusMapV3, VersionAndControlBlock) {
  ModbusServerConfig config = loopback_config();
  config.software_version = 2 << 8 | 17;
  config.software_patch = 4;
  ModbusServer server(config);
  server.start();
  LibmodbusClient plc(server.port());
  EXPECT_GE(plc.read(reg::kMapVersionReg, 1)[0], 3) << "later versions keep every version 3 address";
  EXPECT_EQ(plc.read(reg::kSoftwareVersion, 2), (std::vector<std::uint16_t>{2 << 8 | 17, 4})) << "release 2.17.4";
  EXPECT_EQ(plc.read(55, 9), std::vector<std::uint16_t>(9, 0)) << "55..63 read 0 (map version 4: no second look)";
  EXPECT_EQ(plc.write(reg::kPickResult, {0, 0}), 0) << "4..5 are the PICK_RESULT pair";
  EXPECT_EQ(plc.write(6, {1}), EMBXILADD) << "6..7 stay reserved";
  EXPECT_EQ(plc.write(reg::kCommand, {0, 1, 2, 0, 0, 0, 0}), EMBXILADD) << "a write reaching into 6";
}

// NEXT answers at once: the registers hold the next pick when the answer arrives, JOB_ID_ECHO
// stays, and the daemon hears of it afterwards. With none left it is refused and nothing changes.
TEST(ModbusMapV3, NextWalksTheRankedPicksThenIsRefused) {
  ModbusServer server(loopback_config());
  server.start();
  SimulatedDaemon daemon(server, 20ms);
  LibmodbusClient plc(server.port());

  EXPECT_EQ(plc.write(reg::kCommand, {kNext}), EMBXILVAL) << "no job yet";
  ASSERT_EQ(plc.write(reg::kCommand, {1, 21, 3, 0}), 0);
  expect_pick(wait_for_echo(plc, 21), 21, 0);
  for (std::uint16_t rank = 1; rank < test::kSimPicksPerJob; ++rank) {
    ASSERT_EQ(plc.write(reg::kCommand, {kNext}), 0);
    const auto block = plc.read(0, reg::kBlockSize);  // no polling: the answer came after the change
    expect_pick(block, 21, rank);
    EXPECT_EQ(block[reg::kCommand], 0) << "reads back 0 once taken";
    EXPECT_EQ(block[reg::kLastCommandResult], 0);
    EXPECT_TRUE(eventually([&] { return daemon.nexts.load() == rank; }));
    EXPECT_EQ(daemon.next_rank.load(), rank);
  }
  EXPECT_EQ(plc.write(reg::kCommand, {kNext}), EMBXILVAL) << "none left";
  auto block = plc.read(0, reg::kBlockSize);
  EXPECT_EQ(block[reg::kLastCommandResult], 3);
  expect_pick(block, 21, test::kSimPicksPerJob - 1);
  // The daemon's later reports (it follows with pick_rank) keep the rank the server showed.
  std::this_thread::sleep_for(50ms);
  expect_pick(plc.read(0, reg::kBlockSize), 21, test::kSimPicksPerJob - 1);

  // A new job starts again at its first choice.
  ASSERT_EQ(plc.write(reg::kCommand, {1, 22, 3, 0}), 0);
  expect_pick(wait_for_echo(plc, 22), 22, 0);
  EXPECT_EQ(daemon.nexts.load(), test::kSimPicksPerJob - 1);
}

// FC 0x17: NEXT and the read of the next pick in one exchange.
TEST(ModbusMapV3, NextInOneReadWriteExchange) {
  ModbusServer server(loopback_config());
  server.start();
  SimulatedDaemon daemon(server, 20ms);
  LibmodbusClient plc(server.port());
  ASSERT_EQ(plc.write(reg::kCommand, {1, 30, 3, 0}), 0);
  wait_for_echo(plc, 30);
  const std::uint16_t next = kNext;
  std::vector<std::uint16_t> block(reg::kBlockSize);
  ASSERT_EQ(modbus_write_and_read_registers(plc.ctx, reg::kCommand, 1, &next, 0, reg::kBlockSize, block.data()),
            reg::kBlockSize);
  expect_pick(block, 30, 1);
}

TEST(ModbusMapV3, NextRefusedWhileBusyInErrorOrWithoutPick) {
  ModbusServer server(loopback_config());
  server.start();
  SimulatedDaemon daemon(server, 300ms);
  LibmodbusClient plc(server.port());
  ASSERT_EQ(plc.write(reg::kCommand, {1, 40, 3, 1}), 0);  // COUNT_ONLY: no pick
  EXPECT_EQ(plc.write(reg::kCommand, {kNext}), EMBXSBUSY) << "job 40 still running";
  wait_for_echo(plc, 40);
  EXPECT_EQ(plc.write(reg::kCommand, {kNext}), EMBXILVAL) << "COUNT_ONLY has no pick";
  daemon.fail_next = true;
  ASSERT_EQ(plc.write(reg::kCommand, {1, 41, 3, 0}), 0);
  wait_for_echo(plc, 41);
  EXPECT_EQ(plc.write(reg::kCommand, {kNext}), EMBXSBUSY) << "an error is latched";
  EXPECT_EQ(daemon.nexts.load(), 0);
}

// PICK_RESULT + PICK_RESULT_JOB: reaches the daemon once per pick, only for JOB_ID_ECHO's pick.
TEST(ModbusMapV3, PickResultReachesTheDaemonOncePerPick) {
  ModbusServer server(loopback_config());
  server.start();
  SimulatedDaemon daemon(server, 20ms);
  LibmodbusClient plc(server.port());
  ASSERT_EQ(plc.write(reg::kCommand, {1, 50, 3, 0}), 0);
  wait_for_echo(plc, 50);

  EXPECT_EQ(plc.write(reg::kPickResult, {kMissed, 49}), EMBXILVAL) << "not the job in the registers";
  EXPECT_EQ(plc.write(reg::kPickResult, {9, 50}), EMBXILVAL) << "no such outcome";
  EXPECT_EQ(plc.read(reg::kPickResult, 2), (std::vector<std::uint16_t>{0, 0})) << "refused writes change nothing";
  ASSERT_EQ(plc.write(reg::kPickResult, {kMissed, 50}), 0);
  EXPECT_TRUE(eventually([&] { return daemon.pick_results.load() == 1; }));
  EXPECT_EQ(daemon.result_job.load(), 50);
  EXPECT_EQ(daemon.result_rank.load(), 0);
  EXPECT_EQ(daemon.result_outcome.load(), kMissed);
  EXPECT_EQ(plc.read(reg::kPickResult, 2), (std::vector<std::uint16_t>{kMissed, 50})) << "reads back as written";
  ASSERT_EQ(plc.write(reg::kPickResult, {kMissed, 50}), 0) << "a repeat (a PLC's retry) is acknowledged";
  std::this_thread::sleep_for(50ms);
  EXPECT_EQ(daemon.pick_results.load(), 1) << "... and not counted twice";

  // One write: the report on the pick shown, then NEXT (the robot could not reach it; the next one).
  ASSERT_EQ(plc.write(reg::kCommand, {1, 51, 3, 0, 0, 0}), 0);
  wait_for_echo(plc, 51);
  daemon.order = 0;
  ASSERT_EQ(plc.write(reg::kCommand, {kNext, 51, 3, 0, kUnreachable, 51}), 0);
  expect_pick(plc.read(0, reg::kBlockSize), 51, 1);
  EXPECT_TRUE(eventually([&] { return daemon.nexts.load() == 1 && daemon.pick_results.load() == 2; }));
  EXPECT_EQ(daemon.order.load(), 2u * 4 + 1) << "the report first, then NEXT";
  EXPECT_EQ(daemon.result_rank.load(), 0);
  EXPECT_EQ(daemon.result_outcome.load(), kUnreachable);
  ASSERT_EQ(plc.write(reg::kPickResult, {kOk, 51}), 0);
  EXPECT_TRUE(eventually([&] { return daemon.pick_results.load() == 3; }));
  EXPECT_EQ(daemon.result_rank.load(), 1) << "on the pick NEXT published";
  EXPECT_EQ(daemon.result_outcome.load(), kOk);

  // A refused report refuses the command written with it.
  EXPECT_EQ(plc.write(reg::kCommand, {1, 52, 3, 0, kMissed, 7}), EMBXILVAL);
  EXPECT_EQ(plc.read(reg::kLastCommandResult, 1)[0], 3);
  EXPECT_EQ(daemon.triggers.load(), 2);
  // No pick (COUNT_ONLY): nothing to report on.
  ASSERT_EQ(plc.write(reg::kCommand, {1, 53, 3, 1, 0, 0}), 0);
  wait_for_echo(plc, 53);
  EXPECT_EQ(plc.write(reg::kPickResult, {kMissed, 53}), EMBXILVAL);
}

TEST(ModbusMapV3, SaveSceneIsAJobThatAlsoSaves) {
  ModbusServer server(loopback_config());
  server.start();
  SimulatedDaemon daemon(server, 20ms);
  LibmodbusClient plc(server.port());
  EXPECT_EQ(plc.read(reg::kSnapshotCount, 1)[0], 0);
  ASSERT_EQ(plc.write(reg::kCommand, {kSaveScene, 60, 3, 0}), 0);
  EXPECT_TRUE(plc.read(reg::kStatus, 1)[0] & reg::kBusy);
  const auto block = wait_for_echo(plc, 60);
  EXPECT_EQ(daemon.save_scenes.load(), 1);
  EXPECT_EQ(daemon.triggers.load(), 0);
  EXPECT_EQ(block[reg::kSnapshotCount], 1);
  EXPECT_TRUE(block[reg::kStatus] & reg::kDone);
  EXPECT_EQ(plc.write(reg::kCommand, {kSaveScene, 60, 3, 0}), EMBXILVAL) << "a new job id, as for TRIGGER";
}
