#pragma once
// One multi-flash capture: the scene lit by each LED in turn, plus an image with all LEDs
// off (ambient). The same type comes from the V4L2 camera and from the simulator.

#include <opencv2/core.hpp>

#include <vector>

namespace mfcd::vision {

struct MfcFrames {
  std::vector<cv::Mat1b> flash;  // flash[i] lit by FlashRing::positions_mm[i] (plus ambient light)
  cv::Mat1b ambient;             // all LEDs off
};

}  // namespace mfcd::vision
