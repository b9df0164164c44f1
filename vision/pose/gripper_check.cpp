#include "vision/pose/gripper_check.hpp"

#include <opencv2/core.hpp>

#include <cstdio>
#include <stdexcept>

namespace mfcd::vision {

void GripperCheckParams::validate() const {
  auto fail = [](const std::string& field, const std::string& why) {
    throw std::invalid_argument("gripper check: " + field + " " + why);
  };
  if (!(canny_low >= 0) || !(canny_high >= canny_low)) fail("canny_low/canny_high", "must satisfy 0 <= low <= high");
  if (min_edge_pixels < 0) fail("min_edge_pixels", "must be >= 0");
  if (!(max_cost_px > 0)) fail("max_cost_px", "must be > 0");
  if (!(min_inlier_fraction >= 0 && min_inlier_fraction <= 1)) fail("min_inlier_fraction", "must be in [0, 1]");
  if (!(max_translation_mm >= 0) || !(max_rotation_deg >= 0))
    fail("max_translation_mm/max_rotation_deg", "must be >= 0");
  refiner.validate();
}

const char* to_string(GraspState state) {
  switch (state) {
    case GraspState::expected:
      return "expected";
    case GraspState::pose_error:
      return "pose_error";
    case GraspState::not_grasped:
      return "not_grasped";
  }
  return "?";
}

GripperCheck::GripperCheck(MfcRenderer& renderer, const GripperCheckParams& params)
    : params_(params), canny_(params.canny_low, params.canny_high), refiner_(renderer, params.refiner) {
  params_.validate();
}

GripperCheckResult GripperCheck::check(const PoseModel& model, const RigidTransform& ideal,
                                       std::span<const GripperView> views, PoseRefiner::Clock::time_point deadline) {
  if (views.empty()) throw std::invalid_argument("gripper check: no views given");
  edges_.resize(views.size());
  views_.resize(views.size());
  bool any_edges = false;
  for (size_t k = 0; k < views.size(); ++k) {
    const GripperView& v = views[k];
    const std::string name = "gripper check: view " + std::to_string(k);
    if (v.image.empty()) throw std::invalid_argument(name + ": the image is empty");
    if (v.image.size() != v.camera.image_size)
      throw std::invalid_argument(name + ": image is " + std::to_string(v.image.cols) + "x" +
                                  std::to_string(v.image.rows) + " but its camera is " +
                                  std::to_string(v.camera.image_size.width) + "x" +
                                  std::to_string(v.camera.image_size.height));
    canny_.detect(v.image, edges_[k]);
    any_edges |= cv::countNonZero(edges_[k].edges) >= params_.min_edge_pixels;
    views_[k] = {&edges_[k], v.camera, v.reference_to_camera};
  }
  GripperCheckResult r;
  r.pose = ideal;
  if (!any_edges) {
    r.reason = "fewer than " + std::to_string(params_.min_edge_pixels) + " edge pixels in every view";
    return r;
  }
  // A view without edges cannot be indexed; refine with the views that have some (view 0 is
  // the reference frame's camera, but nothing requires it to be the first one refined).
  size_t used = 0;
  for (size_t k = 0; k < views_.size(); ++k)
    if (cv::countNonZero(edges_[k].edges) > 0) views_[used++] = views_[k];
  views_.resize(used);
  refiner_.prepare(views_);
  r.refinement = refiner_.refine(model, ideal, deadline);
  const RefinementResult& f = r.refinement;
  r.translation_error_mm = translation_difference(ideal, f.pose);
  r.rotation_error_deg = degrees(rotation_difference(ideal, f.pose));
  char buf[256];
  if (f.failed || f.mean_cost_px > params_.max_cost_px || f.inlier_fraction < params_.min_inlier_fraction) {
    std::snprintf(buf, sizeof buf, "part not found: cost %.2f px (max %.2f), inliers %.2f (min %.2f)%s", f.mean_cost_px,
                  params_.max_cost_px, f.inlier_fraction, params_.min_inlier_fraction,
                  f.failed ? ", refinement found too few correspondences" : "");
    r.reason = buf;
    return r;
  }
  r.pose = f.pose;
  const bool off =
      r.translation_error_mm > params_.max_translation_mm || r.rotation_error_deg > params_.max_rotation_deg;
  r.state = off ? GraspState::pose_error : GraspState::expected;
  std::snprintf(buf, sizeof buf,
                "found: cost %.2f px, inliers %.2f, off ideal by %.2f mm, %.2f deg (limits %.2f mm, %.2f deg)",
                f.mean_cost_px, f.inlier_fraction, r.translation_error_mm, r.rotation_error_deg,
                params_.max_translation_mm, params_.max_rotation_deg);
  r.reason = buf;
  return r;
}

}  // namespace mfcd::vision
