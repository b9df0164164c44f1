#include "vision/pipeline/second_look.hpp"

#include "vision/pipeline/pipeline_state.hpp"
#include "vision/pipeline/stage.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace mfcd::vision {

void SecondLookParams::validate() const {
  if (!(tilt_deg >= 5 && tilt_deg <= 60))
    throw std::invalid_argument("second look: tilt_deg " + std::to_string(tilt_deg) + " out of range [5, 60]");
  if (!(same_part_fraction > 0 && same_part_fraction <= 1))
    throw std::invalid_argument("second look: same_part_fraction " + std::to_string(same_part_fraction) +
                                " out of range (0, 1]");
}

SecondLook::SecondLook(const CameraConfig& camera, const PipelineConfig& config, const SecondLookParams& params)
    : params_(params) {
  params_.validate();
  if (config.cost != PipelineConfig::Cost::fdcm) throw std::invalid_argument("second look: needs the FDCM cost");
  first_ = std::make_unique<BinPickingPipeline>(camera, config);
  second_ = std::make_unique<BinPickingPipeline>(camera, config);
}

SecondLook::~SecondLook() = default;

BinPickingPipeline& SecondLook::first() { return *first_; }

RigidTransform SecondLook::suggest_motion(const PoseCandidate& candidate) const {
  const PartModel& part = first_->impl_->part_of(candidate.obj_id);
  const cv::Vec3d c = candidate.R_m2c * part.db.center_mm + candidate.t_m2c_mm;
  if (!(c[2] > 0)) throw std::invalid_argument("second look: the candidate lies behind the camera");
  // Centred: the optical axis turned onto the part centre, x kept as near the first's as it goes.
  const cv::Vec3d z = cv::normalize(c);
  const cv::Vec3d x = cv::normalize(cv::Vec3d(1, 0, 0) - z[0] * z);
  const cv::Vec3d y = z.cross(x);
  const cv::Matx33d centred(x[0], y[0], z[0], x[1], y[1], z[1], x[2], y[2], z[2]);  // columns x, y, z
  // Then turned about the centre: the camera's origin and axes, in the first camera's frame.
  const cv::Matx33d Q = rotation_from_angle_axis(x * (params_.tilt_deg * CV_PI / 180.0));
  const cv::Matx33d R_c2 = Q * centred;
  const cv::Vec3d origin = c - Q * c;
  return {R_c2.t(), -(R_c2.t() * origin)};
}

void SecondLook::fuse(const PipelineResult& first_result, const MfcFrames& second_frames, const RigidTransform& motion,
                      int obj_id, std::chrono::steady_clock::time_point deadline, SecondLookResult& out) {
  out.candidates.clear();
  second_->process(second_frames, obj_id, deadline, out.second);
  BinPickingPipeline::Impl& a = *first_->impl_;
  BinPickingPipeline::Impl& b = *second_->impl_;
  a.prepare_fitter();
  b.prepare_fitter();
  const RigidTransform back = motion.inverse();
  struct Start {
    int obj_id;
    RigidPose pose;
    int proposed_by;
  };
  std::vector<Start> starts;
  for (const auto& c : first_result.candidates) starts.push_back({c.obj_id, {c.R_m2c, c.t_m2c_mm}, 1});
  for (const auto& c : out.second.candidates)
    starts.push_back({c.obj_id, {back.R * c.R_m2c, back.R * c.t_m2c_mm + back.t}, 2});
  const PinholeCamera& cam = a.camera.camera;
  TemplatePoseFit::Workspace& ws_a = a.fit_workspaces[0];
  TemplatePoseFit::Workspace& ws_b = b.fit_workspaces[0];
  for (const Start& s : starts) {
    if (std::chrono::steady_clock::now() >= deadline) break;
    const TemplateDatabase& db = a.part_of(s.obj_id).db;
    const TemplatePoseFit::TwoViewResult j = a.fitter.fit_two_views(db, s.pose, cam, b.fitter, motion, ws_a, ws_b);
    // Ranked as the single-view candidates are: every point of each image's view.
    const TemplateFitResult fa =
        a.fitter.evaluate(db, j.first.view, j.first.pose, cam, ws_a, TemplatePoseFit::kAllPoints);
    const TemplateFitResult fb =
        b.fitter.evaluate(db, j.second.view, j.second.pose, cam, ws_b, TemplatePoseFit::kAllPoints);
    SecondLookCandidate c;
    c.obj_id = s.obj_id;
    c.R_m2c = j.first.pose.R;
    c.t_m2c_mm = j.first.pose.t_mm;
    c.rank_first = fitted_rank(fa, db, a.config);
    c.rank_second = fitted_rank(fb, db, b.config);
    c.rank = c.rank_first + c.rank_second;
    c.proposed_by = s.proposed_by;
    out.candidates.push_back(c);
  }
  std::stable_sort(out.candidates.begin(), out.candidates.end(),
                   [](const SecondLookCandidate& l, const SecondLookCandidate& r) { return l.rank > r.rank; });
  // One per part: a lower-ranked fit whose centre lies near a kept one's is the same part.
  std::vector<SecondLookCandidate> kept;
  for (const auto& c : out.candidates) {
    const TemplateDatabase& db = a.part_of(c.obj_id).db;
    const cv::Vec3d centre = c.R_m2c * db.center_mm + c.t_m2c_mm;
    const bool same = std::any_of(kept.begin(), kept.end(), [&](const SecondLookCandidate& k) {
      if (k.obj_id != c.obj_id) return false;
      return cv::norm(k.R_m2c * db.center_mm + k.t_m2c_mm - centre) < params_.same_part_fraction * db.diameter_mm;
    });
    if (!same) kept.push_back(c);
  }
  out.candidates = std::move(kept);
}

}  // namespace mfcd::vision
