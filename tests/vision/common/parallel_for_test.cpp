// parallel_for: every iteration runs once, and an exception thrown on any thread reaches the
// caller instead of terminating the process.
#include "vision/common/parallel_for.hpp"

#include "tests/hal/alloc_counter.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <string>
#include <vector>

namespace mfcd::vision {
namespace {

TEST(ParallelFor, EveryIterationRunsOnceLikeTheSerialLoop) {
  for (const int threads : {1, 2, 4}) {
    std::vector<std::atomic<int>> runs(1000);
    parallel_for(0, 1000, threads, 3, [&](int i) { runs[static_cast<size_t>(i)].fetch_add(1); });
    for (size_t i = 0; i < runs.size(); ++i)
      ASSERT_EQ(runs[i].load(), 1) << "iteration " << i << ", threads " << threads;
  }
  // An empty or reversed range runs nothing.
  int calls = 0;
  parallel_for(5, 5, 2, 1, [&](int) { ++calls; });
  parallel_for(5, 2, 2, 1, [&](int) { ++calls; });
  EXPECT_EQ(calls, 0);
}

TEST(ParallelFor, AnExceptionOnAnyThreadReachesTheCaller) {
  for (const int threads : {1, 2, 4}) {
    for (const int bad : {0, 17, 999}) {
      std::atomic<int> ran{0};
      try {
        parallel_for(0, 1000, threads, 1, [&](int i) {
          ran.fetch_add(1);
          if (i == bad) throw std::runtime_error("iteration " + std::to_string(i));
        });
        FAIL() << "no exception, threads " << threads;
      } catch (const std::runtime_error& e) {
        EXPECT_EQ(std::string(e.what()), "iteration " + std::to_string(bad));
      }
      EXPECT_GE(ran.load(), 1);
    }
  }
}

TEST(ParallelFor, TheFirstOfSeveralExceptionsIsKept) {
  try {
    parallel_for(0, 64, 2, 1, [&](int i) { throw std::out_of_range(std::to_string(i)); });
    FAIL() << "no exception";
  } catch (const std::out_of_range& e) {
    const int i = std::stoi(e.what());
    EXPECT_GE(i, 0);
    EXPECT_LT(i, 64);
  }
  // After a failure the same code runs normally again (no state survives a call).
  int sum = 0;
  parallel_for(0, 10, 1, 1, [&](int i) { sum += i; });
  EXPECT_EQ(sum, 45);
}

TEST(ParallelFor, SteadyStateAllocatesNothing) {
  std::vector<double> out(256);
  auto body = [&](int i) { out[static_cast<size_t>(i)] = i * 0.5; };
  parallel_for(0, 256, 2, 4, body);  // the OpenMP runtime's thread pool is made here
  const auto before = hal::test::allocation_count();
  for (int k = 0; k < 10; ++k) parallel_for(0, 256, 2, 4, body);
  EXPECT_EQ(hal::test::allocation_count() - before, 0u);
  EXPECT_EQ(out[255], 127.5);
}

TEST(FirstException, NothingCapturedRethrowsNothing) {
  FirstException first;
  EXPECT_FALSE(first.failed());
  EXPECT_FALSE(first.stopping());
  EXPECT_NO_THROW(first.rethrow_if_any());
  try {
    throw std::logic_error("x");
  } catch (...) {
    first.capture();
  }
  EXPECT_TRUE(first.failed());
  EXPECT_THROW(first.rethrow_if_any(), std::logic_error);
}

}  // namespace
}  // namespace mfcd::vision
