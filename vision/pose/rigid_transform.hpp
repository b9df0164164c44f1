#pragma once
// Rigid transforms p_to = R * p_from + t (mm) and the small helpers the pose code needs.
// Angles and axes follow OpenCV's camera convention (x right, y down, z forward).

#include "vision/common/rotation.hpp"

#include <opencv2/core.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace mfcd::vision {

struct RigidTransform {
  cv::Matx33d R = cv::Matx33d::eye();
  cv::Vec3d t{0, 0, 0};

  cv::Vec3d apply(const cv::Vec3d& p) const { return R * p + t; }
  // (this * other)(p) = this(other(p)).
  RigidTransform operator*(const RigidTransform& other) const { return {R * other.R, R * other.t + t}; }
  RigidTransform inverse() const { return {R.t(), -(R.t() * t)}; }
};

// Rotation matrix of an angle-axis vector w (angle = |w| radians), Rodrigues' formula.
inline cv::Matx33d rotation_from_angle_axis(const cv::Vec3d& w) {
  const double th = cv::norm(w);
  if (th < 1e-15) return cv::Matx33d::eye();
  const cv::Vec3d k = w / th;
  const cv::Matx33d Kx(0, -k[2], k[1], k[2], 0, -k[0], -k[1], k[0], 0);
  return cv::Matx33d::eye() + std::sin(th) * Kx + (1 - std::cos(th)) * Kx * Kx;
}

// Angle of the rotation R in radians, [0, pi].
inline double rotation_angle(const cv::Matx33d& R) {
  const double c = std::clamp((cv::trace(R) - 1.0) / 2.0, -1.0, 1.0);
  return std::acos(c);
}

// Angle of the relative rotation between two poses (radians) and the distance between
// their translations (mm).
inline double rotation_difference(const RigidTransform& a, const RigidTransform& b) {
  return rotation_angle(a.R.t() * b.R);
}
inline double translation_difference(const RigidTransform& a, const RigidTransform& b) { return cv::norm(a.t - b.t); }

inline double degrees(double rad) { return rad * 180.0 / std::numbers::pi; }
inline double radians(double deg) { return deg * std::numbers::pi / 180.0; }

}  // namespace mfcd::vision
