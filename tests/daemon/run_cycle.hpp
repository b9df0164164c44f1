#pragma once
// Submits one cycle to a started Cell and waits for its result (other result kinds, such as
// acquisition reports, are skipped). For the in-process Cell tests.
#include <poll.h>

#include <gtest/gtest.h>

#include "daemon/cell.hpp"

namespace mfcd::daemon::test {

inline CycleResult run_cycle(Cell& cell, const CycleRequest& request) {
  EXPECT_TRUE(cell.submit(request));
  for (;;) {
    pollfd p{cell.result_fd(), POLLIN, 0};
    ::poll(&p, 1, 5000);
    if (CycleResult* res = cell.begin_result()) {
      const CycleResult copy = *res;
      cell.end_result();
      if (copy.kind == CycleResult::Kind::Cycle) return copy;
    }
  }
}

}  // namespace mfcd::daemon::test
