#pragma once
// A second look at the bin from another camera pose (paper Sec. 4.5: with the camera on the arm,
// the cell moves it and captures the scene again). Every candidate of the first frame set and of
// the second, the latter mapped into the first camera's frame, is fitted to both images at once
// (TemplatePoseFit::fit_two_views) and ranked by the two images' fitted ranks together. A pose
// that one view cannot tell from a turned or tilted twin is rarely confusable from a camera
// tilted away from the first: the twin's outline and inner edges land elsewhere there.
//
// Owns two pipelines, one per frame set, built from the same configuration (the templates are
// loaded twice). Not thread-safe; fuse() allocates (it is not on the single-view frame path).

#include "vision/pipeline/bin_picking_pipeline.hpp"
#include "vision/pipeline/second_look_fitted.hpp"
#include "vision/pose/rigid_transform.hpp"

#include <chrono>
#include <memory>
#include <vector>

namespace mfcd::vision {

struct SecondLookParams {
  // How far the suggested second camera turns about the candidate's centre, degrees: the out-of-
  // plane change between the two looks. Range [5, 60].
  double tilt_deg = 25;
  // Two fused candidates whose part centres lie nearer than this share of the part's diameter
  // are the same part, and only the better ranked is kept. Range (0, 1].
  double same_part_fraction = 0.25;
  // Two fits of one part are the same pose when their centres lie within this distance, mm, and
  // their rotations within rotation_deg of each other modulo the part's symmetries: the bench's
  // criterion of a right pose. Range (0, 50] mm, (0, 90] degrees.
  double same_pose_mm = 5;
  double same_pose_deg = 10;
  // The fused candidates' confidence (second_look_fitted.hpp, fitted by
  // tools/bench/fit_confidence.py --second-look on the dev split's two-view bins).
  FusedConfidenceModel confidence = kFittedFusedConfidence;
  void validate() const;  // throws std::invalid_argument naming the field
};

struct SecondLookCandidate {
  int obj_id = 0;
  cv::Matx33d R_m2c = cv::Matx33d::eye();  // model -> first camera
  cv::Vec3d t_m2c_mm{0, 0, 0};             // model origin in the first camera's frame, mm
  // The two images' fitted ranks (the measure of PoseCandidate::fit_rank) at the fused pose,
  // and their sum, by which the candidates are ordered.
  double rank_first = 0, rank_second = 0, rank = 0;
  int proposed_by = 1;  // the frame set whose search found the starting pose: 1 or 2
  // The best-ranked other fit of the same part at its place whose pose differs (same_pose_mm,
  // same_pose_deg, symmetries); none when every fit there converged to this pose.
  bool has_alternative = false;
  double alternative_rank = 0;
  // 0..1: the estimated probability that the pose is right (5 mm, 10 degrees), params.confidence.
  double score = 0;

  FusedEvidence evidence() const;
};

struct SecondLookResult {
  std::vector<SecondLookCandidate> candidates;  // best first, one per part
  PipelineResult second;                        // the second frame set's own result (its camera's frame)
  bool degraded = false;  // the deadline cut the second cycle or the fusion short: fewer candidates fused
};

// The bin floor as a camera sees it after `motion` (first camera's frame -> the moved camera's): the
// plane n . X = d becomes (R n) . X' = d + (R n) . t. Unknown (distance 0) where the moved camera
// would see it edge-on or from below, which BinFloor cannot state; unknown stays unknown.
BinFloor floor_after(const BinFloor& floor, const RigidTransform& motion);

class SecondLook {
 public:
  // Throws as BinPickingPipeline's constructor, or std::invalid_argument for bad params.
  SecondLook(const CameraConfig& camera, const PipelineConfig& config, const SecondLookParams& params = {});
  ~SecondLook();
  SecondLook(const SecondLook&) = delete;
  SecondLook& operator=(const SecondLook&) = delete;

  // The pipeline of the first frame set: process() it as every cycle does, then fuse().
  BinPickingPipeline& first();

  // The camera motion (first camera's frame -> second's: p2 = R p1 + t) after which the second
  // camera, at the same distance from the part, has the candidate's centre on its optical axis and
  // sees it turned by params.tilt_deg about the first image's x axis through that centre: the
  // paper's choice of the second location (the part centred, another out-of-plane angle).
  RigidTransform suggest_motion(const PoseCandidate& candidate) const;

  // The second frame set, taken after the camera moved by `motion`, searched for obj_id and fused
  // with `first_result` (the first pipeline's result of its last process(), which fuse() also
  // scores on). Past `deadline` the fusion stops and keeps what it fitted.
  void fuse(const PipelineResult& first_result, const MfcFrames& second_frames, const RigidTransform& motion,
            int obj_id, std::chrono::steady_clock::time_point deadline, SecondLookResult& out);

  // The fused candidates as the first camera's pick candidates, best first: pose, score, rank
  // (fit_rank: the two images' sum), grasp visibility in the first image, the part's projected
  // box. Fields the fusion does not measure keep their defaults; none is ambiguous (the fused
  // score carries the doubt). Allocates.
  void to_pipeline_result(const SecondLookResult& fused, PipelineResult& out) const;

 private:
  SecondLookParams params_;
  std::unique_ptr<BinPickingPipeline> first_, second_;
};

}  // namespace mfcd::vision
