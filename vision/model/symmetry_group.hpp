#pragma once
// The rotations that map a part onto itself, as a group: its exact symmetries (MeshTurns::
// symmetries, found from the mesh) closed under products, and its continuous axes. What it is
// for: telling whether two orientations of the part are the same answer or two different ones.

#include "vision/model/mesh_turns.hpp"

#include <opencv2/core.hpp>

#include <vector>

namespace mfcd::vision {

class SymmetryGroup {
 public:
  SymmetryGroup() = default;  // no symmetry: the identity alone
  // Every product of the finite symmetries (at most kMaxRotations), and the continuous axes.
  explicit SymmetryGroup(const MeshTurns& turns);

  // Degrees between two orientations (model to camera) of the part: the smallest rotation angle
  // of Ra^T Rb S over the group's S. About a continuous axis any turn is the same part, so what
  // is left there is the turn of the axis itself. In [0, 180]. Allocates nothing.
  double angle_deg(const cv::Matx33d& Ra, const cv::Matx33d& Rb) const;

  const std::vector<cv::Matx33d>& rotations() const { return rotations_; }
  const std::vector<cv::Vec3d>& continuous_axes() const { return continuous_; }

  // The largest finite group a rigid part has is the icosahedron's, 60 rotations; a product that
  // would pass this means symmetries that do not form a group (a tolerance too loose).
  static constexpr size_t kMaxRotations = 120;

 private:
  std::vector<cv::Matx33d> rotations_{cv::Matx33d::eye()};
  std::vector<cv::Vec3d> continuous_;
};

}  // namespace mfcd::vision
