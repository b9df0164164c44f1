#pragma once
#include <cstdint>
#include <ctime>

namespace mfcd::hal {

// CLOCK_MONOTONIC in nanoseconds: the clock V4L2 stamps buffers with (V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC),
// so LED on/off times and frame timestamps are directly comparable.
inline std::int64_t monotonic_now_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

}  // namespace mfcd::hal
