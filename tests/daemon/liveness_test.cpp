// The daemon's signs of life on the robot link, end to end on the real process: HEARTBEAT
// follows the health of the frame path, VISION_OK follows the frames, and the last result of a
// stopping daemon reaches a polling PLC before the server closes.
#include <gtest/gtest.h>

#include <signal.h>

#include <vector>

#include "daemon_fixture.hpp"
#include "daemon_process.hpp"
#include "plc_test_client.hpp"

using namespace mfcd::daemon::test;
using namespace mfcd::motion;
using namespace std::chrono_literals;

namespace {

class DaemonLiveness : public DaemonFixture {};

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

}  // namespace

TEST_F(DaemonLiveness, HeartbeatFreezesWhileTheVisionStageHangsAndResumesAfter) {
  // A vision stage that ignores its deadline: the cycle of budget 1 s hangs for 6 s.
  start_daemon("hang", 1000, {"MFCD_TEST_VISION_MS=6000", "MFCD_TEST_VISION_HANG=1"});
  Client plc(port_);
  ASSERT_TRUE(plc.wait_ready());
  Regs r;
  ASSERT_TRUE(plc.read(r));
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_EQ(plc.trigger(3, 0), 0);
  // Heartbeat changes seen while the stage hangs, after the deadline + 3 s (the PLC's rule).
  std::uint16_t last = r.at(reg::kHeartbeat);
  int changes_while_hung = 0, changes_after = 0;
  bool done = false;
  double done_at = 0;
  while (seconds_since(t0) < 11.0) {
    if (!plc.read(r)) continue;
    const double t = seconds_since(t0);
    const std::uint16_t hb = r.at(reg::kHeartbeat);
    if (!done && r.at(reg::kJobIdEcho) == 3) done = true, done_at = t;
    if (hb != last) {
      if (!done && t > 1.0 + 3.0) ++changes_while_hung;
      if (done) ++changes_after;
      last = hb;
    }
    std::this_thread::sleep_for(100ms);
  }
  ASSERT_TRUE(done) << "the hung cycle ended and was published";
  EXPECT_GT(done_at, 5.5);
  EXPECT_EQ(changes_while_hung, 0) << "HEARTBEAT must not advance while the vision thread hangs";
  EXPECT_GE(changes_after, 2) << "HEARTBEAT counts again once the frame path moves";
  EXPECT_NE(proc_->log().find("cycle 1 (plc job 3"), std::string::npos);
}

TEST_F(DaemonLiveness, VisionOkIsClearedByAFailedCycleAndSetByTheNextGoodOne) {
  start_daemon("visionok", 1000, {"MFCD_TEST_VISION_FAIL_FIRST=1"});
  Client plc(port_);
  ASSERT_TRUE(plc.wait_ready());
  Regs r;
  ASSERT_TRUE(plc.read(r));
  EXPECT_TRUE(r.at(reg::kStatus) & reg::kVisionOk);
  ASSERT_EQ(plc.trigger(1, 0), 0);
  ASSERT_TRUE(plc.wait_for(1, r));
  EXPECT_EQ(r.at(reg::kErrorCode), 3) << "vision stage failed";
  EXPECT_FALSE(r.at(reg::kStatus) & reg::kVisionOk);
  ASSERT_EQ(modbus_write_register(plc.ctx, reg::kCommand, 2), 1);  // RESET
  ASSERT_TRUE(plc.wait_ready());
  ASSERT_TRUE(plc.read(r));
  EXPECT_FALSE(r.at(reg::kStatus) & reg::kVisionOk) << "RESET clears the error, not the health";
  ASSERT_EQ(plc.trigger(2, 0), 0);
  ASSERT_TRUE(plc.wait_for(2, r));
  EXPECT_EQ(r.at(reg::kErrorCode), 0);
  EXPECT_TRUE(r.at(reg::kStatus) & reg::kVisionOk);
  EXPECT_TRUE(r.at(reg::kStatus) & reg::kPickValid);
}

TEST_F(DaemonLiveness, TheLastResultReachesAPollingPlcBeforeTheServerCloses) {
  start_daemon("drain", 3000, {"MFCD_TEST_VISION_MS=800"});
  Client plc(port_);
  ASSERT_TRUE(plc.wait_ready());
  ASSERT_EQ(plc.trigger(9, 0), 0);
  std::this_thread::sleep_for(300ms);
  proc_->signal(SIGTERM);
  // A slow PLC: one read every 400 ms, until the server closes the connection.
  Regs r;
  bool saw_result = false;
  const auto t0 = std::chrono::steady_clock::now();
  while (seconds_since(t0) < 10.0) {
    if (!plc.read(r)) break;
    if (r.at(reg::kJobIdEcho) == 9) saw_result = true;
    std::this_thread::sleep_for(400ms);
  }
  EXPECT_TRUE(saw_result) << proc_->log();
  EXPECT_EQ(r.at(reg::kErrorCode), 0);
  const auto code = proc_->wait(10000);
  ASSERT_TRUE(code.has_value());
  EXPECT_EQ(*code, 0);
}
