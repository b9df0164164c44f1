#pragma once
// The daemon's two spellings of a rigid transform: Eigen's (robot and hand-eye poses, from the
// configuration and the PLC) and vision's (poses from and to the pipeline). Both are
// p_to = R * p_from + t in mm; these copy one into the other.

#include <Eigen/Geometry>

#include "vision/pose/rigid_transform.hpp"

namespace mfcd::daemon {

inline Eigen::Isometry3d to_isometry(const cv::Matx33d& R, const cv::Vec3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) T.linear()(r, k) = R(r, k);
    T.translation()(r) = t[r];
  }
  return T;
}

inline Eigen::Isometry3d to_isometry(const vision::RigidTransform& m) { return to_isometry(m.R, m.t); }

inline vision::RigidTransform to_rigid(const Eigen::Isometry3d& T) {
  vision::RigidTransform m;
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) m.R(r, k) = T.linear()(r, k);
    m.t[r] = T.translation()(r);
  }
  return m;
}

}  // namespace mfcd::daemon
