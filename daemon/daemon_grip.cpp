// CHECK_GRIP (config gripper_check, paper Sec. 4.6): the robot holds the part it took before
// the gripper camera; the vision worker compares it with the part where a perfect pick would
// hold it, and the result goes to the robot link's grip registers. Main thread.
#include "daemon/daemon_impl.hpp"
#include "daemon/log.hpp"
#include "daemon/report.hpp"
#include "motion/register_map.hpp"

namespace mfcd::daemon {

namespace {
const char* grip_state_name(std::uint16_t state) {
  static const char* const names[] = {"none", "expected", "pose error", "not grasped"};
  return state < std::size(names) ? names[state] : "?";
}
}  // namespace

void Daemon::start_grip_check(const motion::PlcCommand& cmd) {
  if (!config_.gripper_check.enabled)
    return answer_job(cmd.job_id, cmd.recipe_id, CycleError::NoGripperCheck,
                      "CHECK_GRIP: gripper_check is not configured");
  // The server takes CHECK_GRIP on a published pick; a later cycle may have replaced it since.
  if (last_pick_.job == 0 || last_pick_.job != cmd.check_of_job || cmd.rank >= last_pick_.count)
    return answer_job(cmd.job_id, cmd.recipe_id, CycleError::NoGripperCheck,
                      "CHECK_GRIP: the pick it checks is no longer the one published");
  if (!cell_) return answer_job(cmd.job_id, cmd.recipe_id, CycleError::Unavailable, "no cell is running");
  CycleRequest r;
  r.kind = CycleRequest::Kind::GripCheck;
  r.origin = CycleOrigin::Plc;
  r.cycle_id = next_cycle_++;
  r.job_id = cmd.job_id;
  r.recipe_id = last_pick_.recipe;
  r.obj_id = last_pick_.obj_id[cmd.rank];
  r.trigger = Clock::now();
  r.deadline = r.trigger + std::chrono::milliseconds(config_.cycle_budget_ms);
  r.grip_of_job = cmd.check_of_job;
  // Where a perfect pick holds the part: the tool on the grasp frame.
  r.grip_camera_T_part = config_.gripper_check.tool_T_camera.inverse() * config_.hand_eye.part_T_grasp.inverse();
  if (!submit(r))
    return answer_job(cmd.job_id, cmd.recipe_id, CycleError::Unavailable, "the cell's request queue is full");
  in_flight_ = r;
  update_ready();
}

void Daemon::on_grip_result(const CycleResult& r) {
  last_result_ = result_json(r, config_);
  if (r.error != CycleError::None) {
    logf(LogLevel::Error, "CHECK_GRIP job %u (of job %u): error %u: %s", r.request.job_id, r.request.grip_of_job,
         static_cast<unsigned>(r.error), r.message);
  } else {
    const auto& p = r.grip_pose;
    logf(r.grip_state == static_cast<std::uint16_t>(motion::reg::GripState::Expected) ? LogLevel::Info
                                                                                      : LogLevel::Warning,
         "CHECK_GRIP job %u (of job %u): %s; part in the tool at %.1f %.1f %.1f / %.1f %.1f %.1f, off by %.2f mm "
         "%.2f deg, %.0f ms: %s",
         r.request.job_id, r.request.grip_of_job, grip_state_name(r.grip_state), p.x_mm, p.y_mm, p.z_mm, p.rx_deg,
         p.ry_deg, p.rz_deg, r.grip_translation_mm, r.grip_rotation_deg, r.total_ms, r.message);
  }
  report_.job_id = r.request.job_id;
  report_.recipe_id = r.request.recipe_id;
  report_.error_code = static_cast<std::uint16_t>(r.error);
  report_.cycle_time_ms = static_cast<std::uint16_t>(std::min(65535.0, r.total_ms));
  report_.pick_valid = 0;
  report_.pick = motion::PickPose{};
  report_.score = 0;
  report_.pick_rank = 0;
  report_.pick_count = 0;
  report_.grip_state = r.error == CycleError::None ? r.grip_state : 0;
  report_.grip_of_job = r.request.grip_of_job;
  report_.grip_pose = r.grip_pose;
  report_.grip_translation_mm = r.grip_translation_mm;
  report_.grip_rotation_deg = r.grip_rotation_deg;
  clear_look();
  last_pick_ = {};    // a second check of the same pick would see an empty gripper or the next part
  report_.ready = 0;  // recomputed below, in the same publish
  update_ready();
  publish();
  notify_status();
}

void Daemon::clear_grip() {
  report_.grip_state = 0;
  report_.grip_of_job = 0;
  report_.grip_pose = motion::PickPose{};
  report_.grip_translation_mm = 0;
  report_.grip_rotation_deg = 0;
}

}  // namespace mfcd::daemon
