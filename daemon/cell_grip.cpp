// The cell's gripper check (config gripper_check, CycleRequest::Kind::GripCheck): the acquisition
// thread takes the gripper camera's image, the vision thread checks the part in it.
#include <stdexcept>

#include "daemon/cell.hpp"
#include "daemon/rigid_conversions.hpp"
#include "motion/pick_transform.hpp"
#include "motion/register_map.hpp"

namespace mfcd::daemon {

namespace {
motion::reg::GripState grip_state(vision::GraspState s) {
  switch (s) {
    case vision::GraspState::expected:
      return motion::reg::GripState::Expected;
    case vision::GraspState::pose_error:
      return motion::reg::GripState::PoseError;
    case vision::GraspState::not_grasped:
      break;
  }
  return motion::reg::GripState::NotGrasped;
}
}  // namespace

void Cell::start_gripper_camera() {
  gripper_camera_ = make_gripper_camera(config_, *source_);
  if (!gripper_camera_) return;
  for (auto& slot : frames_.slots()) slot.gripper.create(config_.gripper_check.height, config_.gripper_check.width);
}

void Cell::capture_gripper(FrameSlot& slot) {
  if (!gripper_camera_) throw std::runtime_error("gripper_check is not configured: there is no gripper camera");
  gripper_camera_->capture(slot.request.grip_camera_T_part, slot.gripper);
}

void Cell::check_grip(const FrameSlot& slot, CycleResult& out) {
  const Clock::time_point start = Clock::now();
  if (start_result(slot, CycleResult::Kind::Cycle, out)) {
    out.queue_ms = ms_between(slot.captured, start);
    try {
      const CycleRequest& r = slot.request;
      const vision::GripperCheckResult g = stage_->check_grip(r.obj_id, to_rigid(r.grip_camera_T_part), slot.gripper,
                                                              gripper_pinhole(config_.gripper_check), r.deadline);
      out.grip_state = static_cast<std::uint16_t>(grip_state(g.state));
      if (g.state != vision::GraspState::not_grasped) {
        const motion::PoseXYZ p = motion::isometry_to_pose(config_.gripper_check.tool_T_camera * to_isometry(g.pose));
        out.grip_pose = {static_cast<float>(p.position_mm.x()), static_cast<float>(p.position_mm.y()),
                         static_cast<float>(p.position_mm.z()), static_cast<float>(p.rotation.rx_deg),
                         static_cast<float>(p.rotation.ry_deg), static_cast<float>(p.rotation.rz_deg)};
        out.grip_translation_mm = static_cast<float>(g.translation_error_mm);
        out.grip_rotation_deg = static_cast<float>(g.rotation_error_deg);
      }
      out.grip_cost_px = static_cast<float>(g.refinement.mean_cost_px);
      out.grip_inliers = static_cast<float>(g.refinement.inlier_fraction);
      copy_message(out.message, sizeof out.message, g.reason.c_str());
    } catch (const std::exception& e) {
      out.error = CycleError::Vision;
      copy_message(out.message, sizeof out.message, e.what());
    }
    out.vision_ms = ms_between(start, Clock::now());
  }
  out.total_ms = ms_between(slot.request.trigger, Clock::now());
}

}  // namespace mfcd::daemon
