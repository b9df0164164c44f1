#include "vision/model/symmetry_group.hpp"

#include <algorithm>
#include <cmath>

namespace mfcd::vision {

namespace {

double angle_of(const cv::Matx33d& R) { return std::acos(std::clamp((cv::trace(R) - 1.0) / 2.0, -1.0, 1.0)); }

// Found symmetries are exact to ~1e-6; two products this close are one rotation.
constexpr double kSameRotationRad = 1e-4;

}  // namespace

SymmetryGroup::SymmetryGroup(const MeshTurns& turns) {
  std::vector<cv::Matx33d> generators;
  for (const MeshTurn& t : turns.symmetries) {
    if (t.order == 0)
      continuous_.push_back(t.axis / cv::norm(t.axis));
    else if (t.order >= 2)
      generators.push_back(axis_rotation(t.axis, 2 * CV_PI / t.order));
  }
  for (size_t i = 0; i < rotations_.size() && rotations_.size() < kMaxRotations; ++i)
    for (const cv::Matx33d& g : generators) {
      const cv::Matx33d p = rotations_[i] * g;
      const bool known = std::any_of(rotations_.begin(), rotations_.end(),
                                     [&](const cv::Matx33d& h) { return angle_of(h.t() * p) < kSameRotationRad; });
      if (!known && rotations_.size() < kMaxRotations) rotations_.push_back(p);
    }
}

double SymmetryGroup::angle_deg(const cv::Matx33d& Ra, const cv::Matx33d& Rb) const {
  const cv::Matx33d D = Ra.t() * Rb;
  double best = CV_PI;
  for (const cv::Matx33d& S : rotations_) {
    const cv::Matx33d M = D * S;
    double a = angle_of(M);
    // Any rotation taking the axis to M's image of it turns by at least their angle, and the one
    // about their common normal turns by exactly that and is M times a turn about the axis.
    for (const cv::Vec3d& axis : continuous_) a = std::min(a, std::acos(std::clamp((M * axis).dot(axis), -1.0, 1.0)));
    best = std::min(best, a);
  }
  return best * 180.0 / CV_PI;
}

}  // namespace mfcd::vision
