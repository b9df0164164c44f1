#pragma once
// The bin floor as a constraint on poses. From one view a part's distance is known only from its
// image scale, so a hypothesis fitted onto another part's inner edges can settle at a smaller
// scale, deep down; no real part can lie below the floor the bin stands on. The cell knows where
// the floor is (its distance from the camera), which rules such poses out.

#include "vision/model/mesh.hpp"
#include "vision/pose/coarse_pose.hpp"

#include <opencv2/core.hpp>

namespace mfcd::vision {

struct BinFloor {
  // The plane in the camera frame: points X with normal . X > distance_mm lie below it. normal is
  // a unit vector pointing away from the camera (0, 0, 1 for a camera looking straight down).
  cv::Vec3d normal{0, 0, 1};
  double distance_mm = 0;  // 0: the floor is not known, nothing is below it
  // How far a model may reach below the plane and still count as on it: the floor's calibration
  // and the fit's depth error (fitted poses of parts lying on the floor reach 1-2 mm below it).
  double tolerance_mm = 3;

  bool known() const { return distance_mm > 0; }
  // Throws std::invalid_argument naming the field: negative distance or tolerance, a known floor
  // whose normal is not a unit vector (within 1e-6) or points back towards the camera side
  // (normal . (0, 0, 1) <= 0).
  void validate() const;
  // How far the model reaches below the plane at `pose` (mm; negative: wholly above it). The
  // largest over the mesh's vertices: every surface point is a convex combination of its
  // triangle's vertices, so none reaches deeper than they do.
  double reach_below(const Mesh& model, const RigidPose& pose) const;
  // reach_below > tolerance_mm on a known floor.
  bool below(const Mesh& model, const RigidPose& pose) const;
  // The pose slid along the line of sight through the model point `pivot` (model frame; the
  // part centre a template places) until the model's deepest point lies on the plane: the pivot
  // keeps its image point and the part only changes scale, the one thing a single view measures
  // poorly. The pose unchanged on an unknown floor or when the pivot's camera-frame point P does not
  // lie in front of the camera along the normal (normal . P <= 0).
  RigidPose onto(const Mesh& model, const RigidPose& pose, const cv::Vec3d& pivot) const;
  // An unfitted pose (a search's distance is one of a few guesses) made possible: onto() when it
  // is below(), otherwise the pose itself.
  RigidPose onto_if_below(const Mesh& model, const RigidPose& pose, const cv::Vec3d& pivot) const {
    return below(model, pose) ? onto(model, pose, pivot) : pose;
  }
};

}  // namespace mfcd::vision
