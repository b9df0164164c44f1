#include "motion/seqlock.hpp"
#include "motion/robot_report.hpp"
#include "motion/spsc_ring.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>

using namespace mfcd::motion;

// Every field of the report is derived from one counter; a torn read would mix two.
static RobotReport make_report(std::uint32_t n) {
  RobotReport r;
  r.job_id = static_cast<std::uint16_t>(n);
  r.recipe_id = static_cast<std::uint16_t>(n * 3);
  r.error_code = static_cast<std::uint16_t>(n ^ 0x5a5a);
  r.objects_remaining = static_cast<std::uint16_t>(n >> 3);
  r.pick.x_mm = static_cast<float>(n);
  r.pick.rz_deg = static_cast<float>(n) * 0.5f;
  r.score = static_cast<float>(n & 0xffff) / 65536.0f;
  r.look_reason = static_cast<std::uint16_t>(n % 4);
  r.look_pose.rz_deg = static_cast<float>(n) * 0.25f;
  r.grip_of_job = static_cast<std::uint16_t>(n * 5);
  r.grip_rotation_deg = static_cast<float>(n) * 0.125f;
  return r;
}

static bool consistent(const RobotReport& r) {
  const auto n = static_cast<std::uint32_t>(r.pick.x_mm);
  const RobotReport want = make_report(n);
  return r.job_id == want.job_id && r.recipe_id == want.recipe_id && r.error_code == want.error_code &&
         r.objects_remaining == want.objects_remaining && r.pick.rz_deg == want.pick.rz_deg && r.score == want.score &&
         r.look_reason == want.look_reason && r.look_pose.rz_deg == want.look_pose.rz_deg &&
         r.grip_of_job == want.grip_of_job && r.grip_rotation_deg == want.grip_rotation_deg;
}

TEST(Seqlock, ReadersNeverSeeATornReport) {
  SeqlockSnapshot<RobotReport> board;
  board.publish(make_report(0));
  std::atomic<bool> done{false};
  constexpr std::uint32_t kWrites = 200000;
  std::atomic<std::uint64_t> reads{0};
  std::atomic<bool> torn{false};
  std::atomic<int> started{0};
  const auto reader = [&] {
    std::uint32_t last = 0;
    ++started;
    while (!done.load(std::memory_order_acquire)) {
      const RobotReport r = board.read();
      if (!consistent(r)) torn = true;
      const auto n = static_cast<std::uint32_t>(r.pick.x_mm);
      if (n < last) torn = true;  // went back in time
      last = n;
      reads.fetch_add(1, std::memory_order_relaxed);
    }
  };
  std::thread r1(reader), r2(reader);
  while (started.load() < 2) std::this_thread::yield();
  for (std::uint32_t n = 1; n <= kWrites; ++n) board.publish(make_report(n));
  done = true;
  r1.join();
  r2.join();
  EXPECT_FALSE(torn.load());
  EXPECT_GT(reads.load(), 0u);
  EXPECT_EQ(board.version(), kWrites + 1);
  EXPECT_EQ(board.read().pick.x_mm, static_cast<float>(kWrites));
}

TEST(SpscRingByValue, DeliversEverythingInOrderAcrossThreads) {
  SpscRing<PlcCommand, 16> queue;
  constexpr int kCount = 100000;
  std::thread producer([&] {
    for (int i = 1; i <= kCount;) {
      PlcCommand c;
      c.job_id = static_cast<std::uint16_t>(i);
      c.recipe_id = static_cast<std::uint16_t>(i >> 16);
      if (queue.push(c)) ++i;
    }
  });
  int expected = 1;
  while (expected <= kCount) {
    if (auto c = queue.pop()) {
      ASSERT_EQ(c->job_id, static_cast<std::uint16_t>(expected));
      ASSERT_EQ(c->recipe_id, static_cast<std::uint16_t>(expected >> 16));
      ++expected;
    }
  }
  producer.join();
  EXPECT_FALSE(queue.pop().has_value());
}

TEST(SpscRingByValue, FullQueueRefusesPush) {
  SpscRing<int, 4> queue;
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(queue.push(i));
  EXPECT_FALSE(queue.push(99));
  EXPECT_EQ(queue.pop(), 0);
  EXPECT_TRUE(queue.push(4));
  EXPECT_EQ(queue.size_approx(), 4u);
}
