#pragma once
// The turn about the camera's z axis (its line of sight), which every layer needs: the search's
// in-plane angle, a part's yaw in the bin, a symmetric part's turns, a template view rendered
// turned under the LED ring. It lives here, below them all, so that none has to depend on another
// for one matrix.

#include <opencv2/core.hpp>

#include <cmath>

namespace mfcd::vision {

// Rotation by `a` radians about the z axis (x towards y).
inline cv::Matx33d rotation_about_z(double a) {
  const double c = std::cos(a), s = std::sin(a);
  return {c, -s, 0, s, c, 0, 0, 0, 1};
}

}  // namespace mfcd::vision
