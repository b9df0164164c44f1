#pragma once
// The HalError `f` throws (its code and message are what the hal tests check); a test failure and
// an empty Io error when it throws none.
#include <gtest/gtest.h>

#include <utility>

#include "mfcd/hal/error.hpp"

namespace mfcd::hal::test {

template <typename F>
HalError catch_hal(F&& f) {
  try {
    std::forward<F>(f)();
  } catch (const HalError& e) {
    return e;
  }
  ADD_FAILURE() << "no HalError thrown";
  return HalError(ErrorCode::Io, "");
}

}  // namespace mfcd::hal::test
