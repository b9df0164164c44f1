#pragma once
// Error detection and pose correction in the gripper (paper Sec. 4.6). The part's ideal
// in-gripper pose (model -> gripper camera, what a perfect pick gives) is refined against
// Canny edges of 1..N gripper-camera images (Sec. 4.5's refiner, the ideal pose as the initial
// guess), then the pick is classified:
//   not_grasped  the refined model edges are not found in the images: mean Eq. 21 cost above
//                max_cost_px, inlier fraction below min_inlier_fraction, too few edge pixels,
//                or the refinement failed;
//   pose_error   found, but the refined pose differs from the ideal by more than
//                max_translation_mm or max_rotation_deg: `pose` is the corrected pose;
//   expected     found at the ideal pose (within those limits).

#include "vision/edges/depth_edges.hpp"
#include "vision/pose/pose_refiner.hpp"

#include <opencv2/core.hpp>

#include <span>
#include <string>
#include <vector>

namespace mfcd::vision {

struct GripperView {
  cv::Mat1b image;                     // grey gripper-camera image
  PinholeCamera camera;                // image.size() must equal camera.image_size
  RigidTransform reference_to_camera;  // reference frame (view 0's camera) -> this view's camera
};

struct GripperCheckParams {
  double canny_low = 30, canny_high = 90;
  int min_edge_pixels = 30;  // fewer in every view: nothing in the gripper
  double max_cost_px = 2.0;
  double min_inlier_fraction = 0.6;
  double max_translation_mm = 1.5;
  double max_rotation_deg = 2.0;
  RefinerParams refiner = default_refiner();

  // Canny edges sit on texture and creases too, and the part may sit far from its ideal pose:
  // creases on, a wider initial gate.
  static RefinerParams default_refiner() {
    RefinerParams p;
    p.model_edges.creases = true;
    p.initial_gate_px = 40;
    p.final_gate_px = 4;
    p.gate_shrink_iterations = 12;
    p.max_iterations = 30;
    return p;
  }
  void validate() const;  // throws std::invalid_argument naming the field
};

enum class GraspState { expected, pose_error, not_grasped };
const char* to_string(GraspState state);

struct GripperCheckResult {
  GraspState state = GraspState::not_grasped;
  RigidTransform pose;              // refined (corrected) pose; the ideal one when not grasped
  double translation_error_mm = 0;  // refined vs ideal: distance of the model origins
  double rotation_error_deg = 0;    // refined vs ideal: angle of the relative rotation
  RefinementResult refinement;
  std::string reason;  // why this state, with the figures
};

class GripperCheck {
 public:
  GripperCheck(MfcRenderer& renderer, const GripperCheckParams& params = {});

  // Throws std::invalid_argument naming the view on no views, empty images or mismatched sizes.
  GripperCheckResult check(const PoseModel& model, const RigidTransform& ideal_pose, std::span<const GripperView> views,
                           PoseRefiner::Clock::time_point deadline = PoseRefiner::Clock::time_point::max());

  const GripperCheckParams& params() const { return params_; }
  // Edges of the last check's views (for inspection and overlays).
  const std::vector<DepthEdges>& edges() const { return edges_; }

 private:
  GripperCheckParams params_;
  CannyEdgeDetector canny_;
  PoseRefiner refiner_;
  std::vector<DepthEdges> edges_;
  std::vector<RefinementView> views_;
};

}  // namespace mfcd::vision
