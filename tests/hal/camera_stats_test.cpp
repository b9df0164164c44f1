// Dropped frames are counted from the driver's sequence numbers (V4L2Camera, CameraStats). The
// counter is 32 bits: a gap across its wrap is still a gap, and a number that repeats or steps
// back (a driver restarting its count; vivid on a starved VM delivered sequence 0 twice) must not
// be read as an unsigned underflow of four billion drops.
#include <gtest/gtest.h>

#include <cstdint>

#include "mfcd/hal/camera.hpp"

namespace mfcd::hal {
namespace {

TEST(CameraStats, FramesMissedAreForwardGapsOfTheSequence) {
  EXPECT_EQ(frames_missed_between(5, 6), 0u);
  EXPECT_EQ(frames_missed_between(5, 9), 3u);
  EXPECT_EQ(frames_missed_between(0xFFFFFFFFu, 0), 0u);  // wrap, no gap
  EXPECT_EQ(frames_missed_between(0xFFFFFFFEu, 1), 2u);  // wrap with two missed
}

TEST(CameraStats, RepeatedOrBackwardSequenceIsNoDrop) {
  EXPECT_EQ(frames_missed_between(0, 0), 0u);
  EXPECT_EQ(frames_missed_between(7, 7), 0u);
  EXPECT_EQ(frames_missed_between(9, 5), 0u);
  EXPECT_EQ(frames_missed_between(1000, 0), 0u);  // a restarted count
}

}  // namespace
}  // namespace mfcd::hal
