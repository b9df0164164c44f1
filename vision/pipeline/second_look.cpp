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
  if (!(same_pose_mm > 0 && same_pose_mm <= 50))
    throw std::invalid_argument("second look: same_pose_mm " + std::to_string(same_pose_mm) + " out of range (0, 50]");
  if (!(same_pose_deg > 0 && same_pose_deg <= 90))
    throw std::invalid_argument("second look: same_pose_deg " + std::to_string(same_pose_deg) +
                                " out of range (0, 90]");
}

FusedEvidence SecondLookCandidate::evidence() const {
  return {rank_first, rank_second, has_alternative, has_alternative ? rank - alternative_rank : 0.0};
}

namespace {

double angle_between(const cv::Matx33d& a, const cv::Matx33d& b) { return rotation_angle(a.t() * b); }

// Whether rotations a and b of the part are the same after one of its symmetries (each symmetry
// axis on its own: a turn about one axis composed with one about another is not tried, which
// can only call two poses distinct that are not).
bool same_rotation(const MeshTurns& turns, const cv::Matx33d& a, const cv::Matx33d& b, double tol_rad) {
  if (angle_between(a, b) < tol_rad) return true;
  for (const MeshTurn& s : turns.symmetries) {
    if (s.kind != MeshTurn::Kind::symmetry) continue;
    if (s.order == 0) {  // continuous: any turn about the axis, so only where the axis goes counts
      if (std::acos(std::clamp((a * s.axis).dot(b * s.axis), -1.0, 1.0)) < tol_rad) return true;
      continue;
    }
    cv::Matx33d power = s.R;
    for (int k = 1; k < s.order; ++k, power = power * s.R)
      if (angle_between(a, b * power) < tol_rad) return true;
  }
  return false;
}

}  // namespace

BinFloor floor_after(const BinFloor& floor, const RigidTransform& motion) {
  if (!floor.known()) return floor;
  BinFloor moved = floor;
  moved.normal = motion.R * floor.normal;
  moved.distance_mm = floor.distance_mm + moved.normal.dot(motion.t);
  if (moved.normal[2] <= 0 || moved.distance_mm <= 0) moved.distance_mm = 0;
  return moved;
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
  // The second search keeps its poses above the same floor as the first, seen from where it looks.
  second_->set_floor(floor_after(first_->impl_->config.floor, motion));
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
  out.degraded = out.second.degraded;
  for (const Start& s : starts) {
    if (std::chrono::steady_clock::now() >= deadline) {
      out.degraded = true;
      break;
    }
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
  // One per part: a lower-ranked fit whose centre lies near a kept one's is the same part; the
  // best of those in another pose is the kept one's alternative.
  const double tol_rad = params_.same_pose_deg * CV_PI / 180.0;
  std::vector<SecondLookCandidate> kept;
  for (const auto& c : out.candidates) {
    const TemplateDatabase& db = a.part_of(c.obj_id).db;
    const cv::Vec3d centre = c.R_m2c * db.center_mm + c.t_m2c_mm;
    bool same_part = false;
    for (SecondLookCandidate& k : kept) {
      if (k.obj_id != c.obj_id) continue;
      const double apart = cv::norm(k.R_m2c * db.center_mm + k.t_m2c_mm - centre);
      if (apart >= params_.same_part_fraction * db.diameter_mm) continue;
      same_part = true;
      const bool same_pose = apart < params_.same_pose_mm && same_rotation(db.turns, k.R_m2c, c.R_m2c, tol_rad);
      if (!same_pose && !k.has_alternative) k.has_alternative = true, k.alternative_rank = c.rank;
      break;
    }
    if (!same_part) kept.push_back(c);
  }
  for (SecondLookCandidate& k : kept) k.score = params_.confidence.probability(k.evidence());
  out.candidates = std::move(kept);
}

void SecondLook::to_pipeline_result(const SecondLookResult& fused, PipelineResult& out) const {
  BinPickingPipeline::Impl& a = *first_->impl_;
  const PinholeCamera& cam = a.camera.camera;
  out.candidates.clear();
  for (const SecondLookCandidate& f : fused.candidates) {
    const TemplateDatabase& db = a.part_of(f.obj_id).db;
    PoseCandidate p;
    p.obj_id = f.obj_id;
    p.part = db.part_name;
    p.R_m2c = f.R_m2c;
    p.t_m2c_mm = f.t_m2c_mm;
    p.score = f.score;
    p.fit_rank = f.rank;
    p.refined = true;
    p.has_alternative = f.has_alternative;
    p.alternative_rank = f.alternative_rank;
    p.grasp_visibility = a.best_grasp_visibility(f.obj_id, RigidPose{f.R_m2c, f.t_m2c_mm});
    // The part's sphere (centre, half its diameter) as the image sees it.
    const cv::Vec3d c = f.R_m2c * db.center_mm + f.t_m2c_mm;
    if (c[2] > 0) {
      const double rx = cam.fx() * db.diameter_mm / 2 / c[2], ry = cam.fy() * db.diameter_mm / 2 / c[2];
      const double u = cam.fx() * c[0] / c[2] + cam.cx(), v = cam.fy() * c[1] / c[2] + cam.cy();
      p.box = cv::Rect2d(u - rx, v - ry, 2 * rx, 2 * ry);
    }
    out.candidates.push_back(std::move(p));
  }
}

}  // namespace mfcd::vision
