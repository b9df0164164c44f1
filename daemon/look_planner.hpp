#pragma once
// When an eye-in-hand cell looks at the bin a second time, and from where (docs/pose.md "Second
// look"): the decision after a first look, the flange pose that puts the camera where the vision
// backend wants it, and the camera motion between two flange poses. Pure functions of poses and
// the first look's result.
#include <cstdint>

#include <Eigen/Geometry>

#include "daemon/config.hpp"
#include "daemon/cycle.hpp"
#include "motion/pick_choice.hpp"
#include "motion/register_map.hpp"
#include "vision/pose/rigid_transform.hpp"

namespace mfcd::daemon {

// Why a first look asks for a second: the Modbus LOOK_REASON codes.
using LookReason = motion::reg::LookReason;
const char* to_string(LookReason r);

struct LookDecision {
  LookReason reason = LookReason::None;
  int candidate = -1;  // the candidate to centre the second camera on
};

// After a first look's pick choice (`out`: candidates with their scores and ambiguity, chosen):
// with `always`, a look at the chosen pick (else the best-scored candidate); with `unsure`, a look
// only when no pick was chosen because the best-scored candidate is ambiguous or below
// pick.min_score. None when nothing was found, the cycle failed or counted only.
LookDecision decide_look(SecondLookWhen when, const CycleResult& out, const motion::PickChoiceConfig& pick);

// The camera's motion (first camera's frame -> second's: p2 = R p1 + t, mm) between captures by
// a camera at flange_T_camera on flanges at base_T_flange1 and base_T_flange2.
vision::RigidTransform camera_motion(const Eigen::Isometry3d& base_T_flange1, const Eigen::Isometry3d& base_T_flange2,
                                     const Eigen::Isometry3d& flange_T_camera);

// The flange pose whose camera has moved by `motion` from the capture at base_T_flange1: the
// inverse of camera_motion for the second pose.
Eigen::Isometry3d look_flange_pose(const Eigen::Isometry3d& base_T_flange1, const vision::RigidTransform& motion,
                                   const Eigen::Isometry3d& flange_T_camera);

}  // namespace mfcd::daemon
