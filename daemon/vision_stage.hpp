#pragma once
// The vision worker calls the vision path through this interface. The real backend is
// vision::BinPickingPipeline (PipelineVisionStage); tests put their own backend below it to
// exercise budget, overrun and queue behaviour. Constructed *in* the vision thread: the pipeline
// owns an EGL context bound to the thread that made it.
#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "daemon/config.hpp"
#include "daemon/cycle.hpp"
#include "vision/pipeline/bin_picking_pipeline.hpp"
#include "vision/pose/gripper_check.hpp"
#include "vision/pose/rigid_transform.hpp"

namespace mfcd::daemon {

struct VisionInput {
  const vision::MfcFrames& frames;
  int obj_id = 0;  // 0 = every loaded part
  Clock::time_point deadline;
  // Simulated bin ground truth at capture. Real backends ignore it; it is here so test backends
  // below this interface can answer from the scene.
  const SimTruth* truth = nullptr;
};

class VisionStage {
 public:
  virtual ~VisionStage() = default;
  // Fills `out` (its candidates vector has its capacity reserved once). Must not block past the
  // deadline by more than one stage; sets out.degraded when it cut work short.
  virtual void process(const VisionInput& in, vision::PipelineResult& out) = 0;
  virtual std::vector<std::pair<int, std::string>> parts() const = 0;
  // For snapshots: the depth edges of the last process() (nullptr if none) and an overlay.
  virtual const vision::DepthEdges* last_edges() const = 0;
  virtual cv::Mat3b overlay(const cv::Mat1b& image, const vision::PipelineResult& result) const = 0;
  virtual std::string describe() const = 0;

  // A second look (config second_look). The camera motion (first camera's frame -> second's) that
  // would best separate `candidate` of the last process() from the poses it is confused with;
  // nullopt when this backend cannot look twice.
  virtual std::optional<vision::RigidTransform> suggest_look(const vision::PoseCandidate& candidate) const;
  // The second frame set (`second`, taken after the camera moved by `motion` since the last
  // process()) fused with that process()'s result `first`: candidates in the first camera's frame
  // into `out`. Allocates (a second look is not on the single-look frame path). Throws
  // std::logic_error when this backend cannot look twice.
  virtual void fuse(const vision::PipelineResult& first, const VisionInput& second,
                    const vision::RigidTransform& motion, vision::PipelineResult& out);

  // The gripper check (config gripper_check): part obj_id in `image` of the gripper camera
  // `camera`, ideally at `ideal` (model -> that camera). Allocates on its first call. Throws
  // std::logic_error when this backend cannot check grips, std::invalid_argument for an unknown
  // obj_id.
  virtual vision::GripperCheckResult check_grip(int obj_id, const vision::RigidTransform& ideal, const cv::Mat1b& image,
                                                const vision::PinholeCamera& camera, Clock::time_point deadline);
};

using VisionStageFactory = std::function<std::unique_ptr<VisionStage>(const DaemonConfig&)>;

// True when this mfcd was built with vision/pipeline (the real backend).
bool pipeline_available();
// The pipeline's configuration for `config`: its vision settings, every recipe's template file
// (each once), grasp features and the bin floor. Throws std::runtime_error naming the recipe when
// one has no template file (obj_id 0, "any part", needs none).
vision::PipelineConfig pipeline_config(const DaemonConfig& config);
// The real backend: a BinPickingPipeline over every recipe's template file. Throws
// std::runtime_error naming the recipe/file on a problem.
std::unique_ptr<VisionStage> make_pipeline_stage(const DaemonConfig& config);

}  // namespace mfcd::daemon
