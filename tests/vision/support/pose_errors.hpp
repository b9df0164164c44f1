#pragma once
// The vision tests' rotation error: the angle (degrees) between two model -> camera rotations,
// the smallest over the part's symmetries; for a part round about its z axis, the angle between
// the two z axes (only the axis's direction is the pose).
#include "vision/templates/template_database.hpp"

#include <opencv2/core.hpp>

#include <algorithm>
#include <cmath>

namespace mfcd::vision::testing {

inline double rotation_error_deg(const cv::Matx33d& a, const cv::Matx33d& b, const PartSymmetry& sym) {
  if (sym.kind == PartSymmetry::Kind::continuous_z) {
    const cv::Vec3d za(a(0, 2), a(1, 2), a(2, 2)), zb(b(0, 2), b(1, 2), b(2, 2));
    return std::acos(std::clamp(za.dot(zb), -1.0, 1.0)) * 180 / CV_PI;
  }
  double best = 1e9;
  for (const auto& S : sym.discrete_rotations()) {
    const cv::Matx33d d = a.t() * b * S;
    best = std::min(best, std::acos(std::clamp((cv::trace(d) - 1) / 2, -1.0, 1.0)) * 180 / CV_PI);
  }
  return best;
}

}  // namespace mfcd::vision::testing
