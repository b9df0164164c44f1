#include "daemon/look_planner.hpp"

#include "daemon/rigid_conversions.hpp"

namespace mfcd::daemon {

const char* to_string(LookReason r) {
  switch (r) {
    case LookReason::None:
      return "none";
    case LookReason::Always:
      return "always";
    case LookReason::Ambiguous:
      return "ambiguous";
    case LookReason::LowScore:
      return "low score";
  }
  return "?";
}

LookDecision decide_look(SecondLookWhen when, const CycleResult& out, const motion::PickChoiceConfig& pick) {
  if (when == SecondLookWhen::Off || out.error != CycleError::None || out.request.mode != 0 || out.candidate_count == 0)
    return {};
  int best = 0;
  for (int i = 1; i < out.candidate_count; ++i)
    if (out.candidates[static_cast<std::size_t>(i)].score > out.candidates[static_cast<std::size_t>(best)].score)
      best = i;
  if (when == SecondLookWhen::Always) return {LookReason::Always, out.chosen >= 0 ? out.chosen : best};
  if (out.chosen >= 0) return {};
  const CandidateOut& c = out.candidates[static_cast<std::size_t>(best)];
  if (pick.skip_ambiguous && c.ambiguous) return {LookReason::Ambiguous, best};
  if (c.score < pick.min_score) return {LookReason::LowScore, best};
  return {};  // withheld for another reason (grasp visibility, reach): a second look would not help
}

vision::RigidTransform camera_motion(const Eigen::Isometry3d& base_T_flange1, const Eigen::Isometry3d& base_T_flange2,
                                     const Eigen::Isometry3d& flange_T_camera) {
  const Eigen::Isometry3d camera2_T_camera1 =
      (base_T_flange2 * flange_T_camera).inverse() * (base_T_flange1 * flange_T_camera);
  return to_rigid(camera2_T_camera1);
}

Eigen::Isometry3d look_flange_pose(const Eigen::Isometry3d& base_T_flange1, const vision::RigidTransform& motion,
                                   const Eigen::Isometry3d& flange_T_camera) {
  return base_T_flange1 * flange_T_camera * to_isometry(motion).inverse() * flange_T_camera.inverse();
}

}  // namespace mfcd::daemon
