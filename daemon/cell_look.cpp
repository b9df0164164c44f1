// The cell's second look (config second_look, eye-in-hand): the first look asks for it, the
// second is fused with it. Vision thread.
#include <stdexcept>
#include <string>
#include <utility>

#include "daemon/cell.hpp"
#include "daemon/look_planner.hpp"
#include "motion/pick_transform.hpp"

namespace mfcd::daemon {

void Cell::plan_look(const CycleRequest& request, CycleResult& out) {
  const LookDecision d = decide_look(config_.second_look.when, out, config_.pick.choice);
  if (d.reason == LookReason::None || !request.flange_valid) return;
  const auto motion = stage_->suggest_look(pipeline_result_.candidates[static_cast<std::size_t>(d.candidate)]);
  if (!motion) return;
  const motion::PoseXYZ flange =
      motion::isometry_to_pose(look_flange_pose(request.base_T_flange, *motion, config_.hand_eye.camera));
  out.look_wanted = true;
  out.look_reason = static_cast<std::uint16_t>(d.reason);
  out.look_candidate = d.candidate;
  out.look_pose = {static_cast<float>(flange.position_mm.x()), static_cast<float>(flange.position_mm.y()),
                   static_cast<float>(flange.position_mm.z()), static_cast<float>(flange.rotation.rx_deg),
                   static_cast<float>(flange.rotation.ry_deg), static_cast<float>(flange.rotation.rz_deg)};
  // The pick waits for the second look.
  out.chosen = -1;
  out.ranked_count = 0;
  // Kept without a copy: the next single look writes into the other result's storage.
  std::swap(first_look_, pipeline_result_);
  first_look_cycle_ = request.cycle_id;
}

void Cell::fuse_look(const VisionInput& in, const CycleRequest& request) {
  if (first_look_cycle_ == 0 || first_look_cycle_ != request.first_cycle)
    throw std::runtime_error("second look: cycle " + std::to_string(request.first_cycle) +
                             "'s first look is no longer kept (a later cycle ran in between)");
  first_look_cycle_ = 0;  // one second look per first
  stage_->fuse(first_look_, in,
               camera_motion(request.first_base_T_flange, request.base_T_flange, config_.hand_eye.camera),
               pipeline_result_);
}

}  // namespace mfcd::daemon
