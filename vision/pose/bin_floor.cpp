#include "vision/pose/bin_floor.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace mfcd::vision {

void BinFloor::validate() const {
  if (!(distance_mm >= 0)) throw std::invalid_argument("bin floor: distance_mm must be >= 0 (0 = not known)");
  if (!(tolerance_mm >= 0)) throw std::invalid_argument("bin floor: tolerance_mm must be >= 0");
  if (!known()) return;
  if (!(std::abs(cv::norm(normal) - 1.0) <= 1e-6))
    throw std::invalid_argument("bin floor: normal must be a unit vector");
  if (!(normal[2] > 0)) throw std::invalid_argument("bin floor: normal must point away from the camera (z > 0)");
}

double BinFloor::reach_below(const Mesh& model, const RigidPose& pose) const {
  // normal . (R p + t) = (R^T normal) . p + normal . t: one dot product per vertex.
  const cv::Vec3d n_model = pose.R.t() * normal;
  double deepest = -std::numeric_limits<double>::infinity();
  for (const cv::Vec3f& p : model.vertices) deepest = std::max(deepest, n_model.dot(cv::Vec3d(p[0], p[1], p[2])));
  return deepest + normal.dot(pose.t_mm) - distance_mm;
}

bool BinFloor::below(const Mesh& model, const RigidPose& pose) const {
  return known() && reach_below(model, pose) > tolerance_mm;
}

RigidPose BinFloor::onto(const Mesh& model, const RigidPose& pose, const cv::Vec3d& pivot) const {
  const cv::Vec3d P = pose.R * pivot + pose.t_mm;
  const double along = normal.dot(P);
  if (!known() || !(along > 0)) return pose;
  // The pivot goes to s P and every model point moves with it by (s - 1) P, so the deepest
  // point's depth below the plane changes by (s - 1) normal . P: s = 1 - reach / along puts it on
  // the plane.
  const double s = 1.0 - reach_below(model, pose) / along;
  RigidPose moved = pose;
  moved.t_mm = s * P - pose.R * pivot;
  return moved;
}

}  // namespace mfcd::vision
