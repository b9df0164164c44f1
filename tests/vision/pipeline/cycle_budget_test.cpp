// The cycle's deadline rules (vision/pipeline/cycle_budget.hpp), on deadlines far from now so that
// the test's own run time does not matter.
#include "vision/pipeline/cycle_budget.hpp"

#include <gtest/gtest.h>

namespace mfcd::vision::detail {
namespace {

using Clock = CycleBudget::Clock;
using std::chrono::milliseconds;

double ms_before(Clock::time_point deadline, Clock::time_point t) { return ms_between(t, deadline); }

TEST(CycleBudget, SearchLeavesTheFitOneAndAHalfItsEstimateButAtMostHalfTheTimeLeft) {
  CycleBudget b(2);  // first estimate: 2 ms / 2 threads = 1 ms a hypothesis
  const auto deadline = Clock::now() + milliseconds(10000);
  b.start(deadline);
  EXPECT_NEAR(ms_before(deadline, b.search_deadline(48)), 72, 1e-6);  // 1.5 x 48 x 1 ms
  b.record_fit(30, 12);  // a fit cut short at 12: 2.5 ms a hypothesis, 120 ms for 48
  EXPECT_NEAR(ms_before(deadline, b.search_deadline(48)), 180, 1e-6);
  EXPECT_NEAR(ms_before(deadline, b.search_deadline(96)), 360, 1e-6);  // a cycle of more types
  // Nothing fitted: the estimate stays.
  b.record_fit(30, 0);
  EXPECT_NEAR(ms_before(deadline, b.search_deadline(48)), 180, 1e-6);
  const auto soon = Clock::now() + milliseconds(200);
  b.start(soon);
  const double left = ms_between(Clock::now(), soon);
  const double left_for_fit = ms_before(soon, b.search_deadline(48));
  EXPECT_LE(left_for_fit, 0.5 * left + 1e-6);  // half of the ~200 ms, not 180
  EXPECT_GT(left_for_fit, 0.5 * (left - 50));
  b.start(Clock::now() - milliseconds(5));  // already late: the search has until the deadline
  EXPECT_EQ(b.search_deadline(48), b.deadline());
}

TEST(CycleBudget, OptionalStagesStartOnlyWhenTheirLastTimeFits) {
  CycleBudget b(2);
  b.start(Clock::now() + milliseconds(1000));
  EXPECT_TRUE(b.leaves_time_for(CycleBudget::Optional::round));  // never ran: 0 ms
  EXPECT_TRUE(b.leaves_time_for(CycleBudget::Optional::escalation));
  b.record(CycleBudget::Optional::round, 5000);
  EXPECT_FALSE(b.leaves_time_for(CycleBudget::Optional::round));
  EXPECT_TRUE(b.leaves_time_for(CycleBudget::Optional::escalation));  // each stage its own estimate
  b.record(CycleBudget::Optional::escalation, 100);
  EXPECT_TRUE(b.leaves_time_for(CycleBudget::Optional::escalation));
  b.start(Clock::now() - milliseconds(1));
  EXPECT_FALSE(b.leaves_time_for(CycleBudget::Optional::escalation));
}

}  // namespace
}  // namespace mfcd::vision::detail
