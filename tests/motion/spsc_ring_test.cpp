// The lock-free SPSC ring of preallocated slots: against a single-threaded reference model on
// random operation sequences, and across two threads (run this binary under the tsan preset).
#include <gtest/gtest.h>

#include <deque>
#include <random>
#include <thread>

#include "motion/spsc_ring.hpp"

using mfcd::motion::SpscRing;

namespace {
struct Payload {
  std::uint64_t seq = 0;
  std::array<std::uint64_t, 32> words{};  // a "large" slot, filled in place
};
}  // namespace

TEST(SpscRing, MatchesAQueueModelOnRandomOperations) {
  std::mt19937 rng(7);
  SpscRing<Payload, 8> ring;
  std::deque<std::uint64_t> model;
  std::uint64_t next = 1;
  for (int op = 0; op < 200000; ++op) {
    if (rng() % 2) {
      Payload* p = ring.begin_write();
      ASSERT_EQ(p == nullptr, model.size() == 8) << "full exactly when the model holds 8";
      if (p) {
        p->seq = next;
        p->words.fill(next * 3);
        ring.end_write();
        model.push_back(next++);
      }
    } else {
      Payload* p = ring.begin_read();
      ASSERT_EQ(p == nullptr, model.empty());
      if (p) {
        ASSERT_EQ(p->seq, model.front());
        ASSERT_EQ(p->words[31], model.front() * 3);
        ring.end_read();
        model.pop_front();
      }
    }
    ASSERT_EQ(ring.size_approx(), model.size());
  }
}

TEST(SpscRing, TwoThreadsSeeEverySlotWholeAndInOrder) {
  SpscRing<Payload, 4> ring;
  constexpr std::uint64_t kCount = 200000;
  std::thread producer([&] {
    for (std::uint64_t i = 1; i <= kCount;) {
      Payload* p = ring.begin_write();
      if (!p) {
        std::this_thread::yield();
        continue;
      }
      p->seq = i;
      for (auto& w : p->words) w = i ^ 0x5a5a5a5aull;
      ring.end_write();
      ++i;
    }
  });
  std::uint64_t expected = 1;
  while (expected <= kCount) {
    Payload* p = ring.begin_read();
    if (!p) {
      std::this_thread::yield();
      continue;
    }
    ASSERT_EQ(p->seq, expected);
    for (auto w : p->words) ASSERT_EQ(w, expected ^ 0x5a5a5a5aull) << "torn slot";
    ring.end_read();
    ++expected;
  }
  producer.join();
  EXPECT_EQ(ring.size_approx(), 0u);
}
