// Render-based refinement of the best candidates (paper Sec. 4.5; one view here: the cell's
// single MFC capture), until the deadline.
#include "vision/pipeline/stage.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>

namespace mfcd::vision {

void BinPickingPipeline::Impl::ensure_renderer() {
  if (renderer) return;
  renderer = std::make_unique<MfcRenderer>(camera);
  for (const auto& part : parts) mesh_ids.push_back(renderer->add_mesh(part.db.mesh));
  RefinerParams rp;
  rp.max_iterations = config.refine_iterations;
  refiner = std::make_unique<PoseRefiner>(*renderer, rp);
}

std::unique_ptr<GripperCheck> BinPickingPipeline::make_gripper_check(const GripperCheckParams& params) {
  impl_->ensure_renderer();
  return std::make_unique<GripperCheck>(*impl_->renderer, params);
}

PoseModel BinPickingPipeline::pose_model_of(int obj_id) {
  impl_->ensure_renderer();
  for (std::size_t k = 0; k < impl_->parts.size(); ++k)
    if (impl_->parts[k].db.obj_id == obj_id) return pose_model(impl_->mesh_ids[k], impl_->parts[k].db.mesh);
  throw std::invalid_argument("pipeline: no templates loaded for obj_id " + std::to_string(obj_id));
}

void BinPickingPipeline::Impl::refine(Clock::time_point deadline, PipelineResult& out) {
  // Multi-view refinement (paper Sec. 4.5; one view here: the cell's single MFC capture) of the
  // best candidates, until the deadline. A candidate whose refinement fails keeps its coarse pose.
  const int refine = config.refine_iterations > 0
                         ? std::min<int>(config.refine_candidates, static_cast<int>(out.candidates.size()))
                         : 0;
  if (refine > 0 && Clock::now() < deadline) {
    ensure_renderer();
    const RefinementView view{&edges, camera.camera, RigidTransform{}};
    refiner->prepare(std::span<const RefinementView>(&view, 1));
    for (int i = 0; i < refine; ++i) {
      if (Clock::now() >= deadline) {
        out.degraded = true;
        break;
      }
      PoseCandidate& c = out.candidates[i];
      int part = 0;
      while (parts[part].db.obj_id != c.obj_id) ++part;
      const RefinementResult r = refiner->refine(pose_model(mesh_ids[part], parts[part].db.mesh),
                                                 RigidTransform{c.R_m2c, c.t_m2c_mm}, deadline);
      out.degraded = out.degraded || r.deadline_hit;
      if (r.failed) continue;
      // One view constrains depth and tilt weakly; a refinement that ends worse than it started
      // (by the same Eq. 21 measure) walked into a false minimum: keep the coarse pose then.
      const RefinementResult start =
          refiner->evaluate(pose_model(mesh_ids[part], parts[part].db.mesh), RigidTransform{c.R_m2c, c.t_m2c_mm});
      // Depth is where one view is weakest: a flat part can trade distance for tilt. The coarse
      // distance was measured from the image scale (fit_distance, 1 % steps, then the hypothesis fit), so a refinement
      // that moves the part centre along the line of sight by more than 4 % of its distance is not trusted either.
      const cv::Vec3d c0 = c.R_m2c * parts[part].db.center_mm + c.t_m2c_mm;
      const cv::Vec3d c1 = r.pose.R * parts[part].db.center_mm + r.pose.t;
      const bool depth_jump = std::abs(cv::norm(c1) - cv::norm(c0)) > 0.04 * cv::norm(c0);
      if (r.score < start.score || depth_jump) {
        c.cost_px = start.mean_cost_px;
        continue;
      }
      c.R_m2c = r.pose.R;
      c.t_m2c_mm = r.pose.t;
      c.cost_px = r.mean_cost_px;
      c.refined = true;
    }
    // The order stays the fitted ranking's (TemplatePoseFit with the unexplained-edge check): the
    // refiner polishes a pose, its score (model edges found, no converse check) does not tell a
    // part from its own back or from clutter as well.
  }
}

namespace detail {

namespace {

class RefinementStage final : public Stage {
 public:
  RefinementStage() : Stage("refinement", &StageTimes::refine_ms) {}
  void run(BinPickingPipeline::Impl& m, CycleContext& c) override { m.refine(c.cycle.deadline, *c.out); }
};

// Grasp features at the final poses: edges and the part's own points only, ~0.1 ms each. A part
// type without any keeps 1.
class GraspStage final : public Stage {
 public:
  GraspStage() : Stage("grasp", &StageTimes::refine_ms) {}
  void run(BinPickingPipeline::Impl& m, CycleContext& c) override {
    for (PoseCandidate& p : c.out->candidates)
      p.grasp_visibility = m.best_grasp_visibility(p.obj_id, RigidPose{p.R_m2c, p.t_m2c_mm});
  }
};

}  // namespace

std::unique_ptr<Stage> make_refinement_stage() { return std::make_unique<RefinementStage>(); }
std::unique_ptr<Stage> make_grasp_stage() { return std::make_unique<GraspStage>(); }

}  // namespace detail

}  // namespace mfcd::vision
