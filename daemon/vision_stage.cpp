#include "daemon/vision_stage.hpp"

#include <algorithm>
#include <stdexcept>

#include "vision/camera/camera.hpp"
#ifdef MFCD_HAVE_PIPELINE
#include "vision/pipeline/second_look.hpp"
#endif

namespace mfcd::daemon {

std::optional<vision::RigidTransform> VisionStage::suggest_look(const vision::PoseCandidate&) const {
  return std::nullopt;
}

void VisionStage::fuse(const vision::PipelineResult&, const VisionInput&, const vision::RigidTransform&,
                       vision::PipelineResult&) {
  throw std::logic_error(describe() + " cannot look twice");
}

vision::GripperCheckResult VisionStage::check_grip(int, const vision::RigidTransform&, const cv::Mat1b&,
                                                   const vision::PinholeCamera&, Clock::time_point) {
  throw std::logic_error(describe() + " cannot check grips");
}

vision::PipelineConfig pipeline_config(const DaemonConfig& config) {
  vision::PipelineConfig pc = config.vision.pipeline;
  for (const auto& r : config.recipes) {
    if (!r.templates) {
      if (r.obj_id != 0)
        throw std::runtime_error(config.source + ": recipe " + std::to_string(r.id) + " (" + r.part +
                                 "): 'templates' is required by the vision pipeline");
      continue;
    }
    if (std::find(pc.template_files.begin(), pc.template_files.end(), *r.templates) == pc.template_files.end())
      pc.template_files.push_back(*r.templates);
  }
  if (pc.template_files.empty())
    throw std::runtime_error(config.source +
                             ": recipes: no recipe names a template file; the vision pipeline has nothing to look for");
  for (const auto& r : config.recipes)
    for (const GraspFeatureSetting& g : r.grasp_features) {
      vision::GraspFeature f;
      f.point_mm = {g.x_mm, g.y_mm, g.z_mm};
      f.radius_mm = g.radius_mm;
      f.approach = {g.approach[0], g.approach[1], g.approach[2]};
      f.max_tilt_deg = g.max_tilt_deg;
      pc.grasp_features.emplace_back(r.obj_id, f);
    }
  if (config.vision.floor_check)
    pc.floor.distance_mm = config.pick.bin_floor_distance_mm;  // the camera looks straight down at it
  return pc;
}

#ifdef MFCD_HAVE_PIPELINE

namespace {

// gripper_check's limits over the gripper check's defaults.
vision::GripperCheckParams gripper_check_params(const GripperCheckSettings& s) {
  vision::GripperCheckParams p;
  p.max_translation_mm = s.max_translation_mm;
  p.max_rotation_deg = s.max_rotation_deg;
  p.max_cost_px = s.max_cost_px;
  p.min_inlier_fraction = s.min_inlier_fraction;
  return p;
}

// One BinPickingPipeline; with second_look a vision::SecondLook, whose first pipeline serves
// every single look (the second's templates are loaded too).
class PipelineVisionStage final : public VisionStage {
 public:
  PipelineVisionStage(const vision::CameraConfig& camera, vision::PipelineConfig config, std::string files,
                      const SecondLookSettings& look, const GripperCheckSettings& grip)
      : files_(std::move(files)), grip_params_(gripper_check_params(grip)) {
    if (look.when == SecondLookWhen::Off) {
      single_ = std::make_unique<vision::BinPickingPipeline>(camera, std::move(config));
    } else {
      vision::SecondLookParams params;
      params.tilt_deg = look.tilt_deg;
      look_ = std::make_unique<vision::SecondLook>(camera, config, params);
    }
  }
  void process(const VisionInput& in, vision::PipelineResult& out) override {
    pipeline().process(in.frames, in.obj_id, in.deadline, out);
    have_edges_ = true;
  }
  std::vector<std::pair<int, std::string>> parts() const override { return pipeline().parts(); }
  const vision::DepthEdges* last_edges() const override { return have_edges_ ? &pipeline().last_edges() : nullptr; }
  cv::Mat3b overlay(const cv::Mat1b& image, const vision::PipelineResult& result) const override {
    return vision::draw_candidates(image, result, pipeline().camera());
  }
  std::string describe() const override {
    return std::string(look_ ? "BinPickingPipeline with second look (" : "BinPickingPipeline (") + files_ + ")";
  }
  std::optional<vision::RigidTransform> suggest_look(const vision::PoseCandidate& candidate) const override {
    if (!look_) return std::nullopt;
    return look_->suggest_motion(candidate);
  }
  void fuse(const vision::PipelineResult& first, const VisionInput& second, const vision::RigidTransform& motion,
            vision::PipelineResult& out) override {
    if (!look_) VisionStage::fuse(first, second, motion, out);
    look_->fuse(first, second.frames, motion, second.obj_id, second.deadline, fused_);
    look_->to_pipeline_result(fused_, out);
    out.times = fused_.second.times;
    out.degraded = fused_.degraded;
    out.edge_pixels = fused_.second.edge_pixels;
    out.rounds = fused_.second.rounds;
    out.escalated = fused_.second.escalated;
    // The edges kept for snapshots are the first image's; the frames of this cycle are the second.
    have_edges_ = false;
  }
  vision::GripperCheckResult check_grip(int obj_id, const vision::RigidTransform& ideal, const cv::Mat1b& image,
                                        const vision::PinholeCamera& camera, Clock::time_point deadline) override {
    if (!grip_) grip_ = pipeline().make_gripper_check(grip_params_);
    const vision::GripperView view{image, camera, vision::RigidTransform{}};
    return grip_->check(pipeline().pose_model_of(obj_id), ideal, std::span<const vision::GripperView>(&view, 1),
                        deadline);
  }

 private:
  vision::BinPickingPipeline& pipeline() const { return look_ ? look_->first() : *single_; }

  std::unique_ptr<vision::BinPickingPipeline> single_;
  std::unique_ptr<vision::SecondLook> look_;
  vision::SecondLookResult fused_;
  std::string files_;
  bool have_edges_ = false;
  vision::GripperCheckParams grip_params_;
  std::unique_ptr<vision::GripperCheck> grip_;  // made on the first check (it renders)
};

}  // namespace

bool pipeline_available() { return true; }

std::unique_ptr<VisionStage> make_pipeline_stage(const DaemonConfig& config) {
  const vision::CameraConfig camera = vision::load_camera_config(config.camera.model);
  vision::PipelineConfig pc = pipeline_config(config);
  std::string files;
  for (const auto& f : pc.template_files) files += (files.empty() ? "" : ", ") + f.filename().string();
  auto stage =
      std::make_unique<PipelineVisionStage>(camera, std::move(pc), files, config.second_look, config.gripper_check);
  // Every recipe's obj_id must be one the templates define.
  const auto loaded = stage->parts();
  for (const auto& r : config.recipes) {
    if (r.obj_id == 0) continue;
    bool found = false;
    for (const auto& [id, name] : loaded) found = found || id == r.obj_id;
    if (!found)
      throw std::runtime_error(config.source + ": recipe " + std::to_string(r.id) + " (" + r.part + "): obj_id " +
                               std::to_string(r.obj_id) + " is not in any loaded template file (" + files + ")");
  }
  return stage;
}

#else

bool pipeline_available() { return false; }

std::unique_ptr<VisionStage> make_pipeline_stage(const DaemonConfig&) {
  throw std::runtime_error(
      "this mfcd was built without vision/pipeline (target mfcd_vision_pipeline), so it has no vision backend");
}

#endif

}  // namespace mfcd::daemon
