#include "daemon/look_planner.hpp"

namespace mfcd::daemon {

namespace {

Eigen::Isometry3d toIsometry(const vision::RigidTransform& m) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) T.linear()(r, k) = m.R(r, k);
    T.translation()(r) = m.t[r];
  }
  return T;
}

}  // namespace

const char* toString(LookReason r) {
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

LookDecision decideLook(SecondLookWhen when, const CycleResult& out, const motion::PickChoiceConfig& pick) {
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

vision::RigidTransform cameraMotion(const Eigen::Isometry3d& base_T_flange1, const Eigen::Isometry3d& base_T_flange2,
                                    const Eigen::Isometry3d& flange_T_camera) {
  const Eigen::Isometry3d camera2_T_camera1 =
      (base_T_flange2 * flange_T_camera).inverse() * (base_T_flange1 * flange_T_camera);
  vision::RigidTransform m;
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) m.R(r, k) = camera2_T_camera1.linear()(r, k);
    m.t[r] = camera2_T_camera1.translation()(r);
  }
  return m;
}

Eigen::Isometry3d lookFlangePose(const Eigen::Isometry3d& base_T_flange1, const vision::RigidTransform& motion,
                                 const Eigen::Isometry3d& flange_T_camera) {
  return base_T_flange1 * flange_T_camera * toIsometry(motion).inverse() * flange_T_camera.inverse();
}

}  // namespace mfcd::daemon
