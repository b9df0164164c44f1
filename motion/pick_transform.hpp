// Camera-frame part pose -> robot base-frame pick pose, with the hand-eye calibration.
//
//   eye-in-hand (camera on the flange): base_T_cam = base_T_flange * flange_T_cam, where
//       base_T_flange is the robot pose at the moment of capture;
//   eye-to-hand (camera fixed over the bin): base_T_cam is the calibration itself.
//   base_T_pick = base_T_cam * cam_T_part * part_T_grasp
// All translations in millimetres.
#pragma once

#include "motion/euler.hpp"
#include "motion/robot_report.hpp"

#include <Eigen/Geometry>
#include <optional>
#include <string>

namespace mfcd::motion {

enum class HandEyeSetup { EyeInHand, EyeToHand };

struct HandEyeCalibration {
  HandEyeSetup setup = HandEyeSetup::EyeToHand;
  // EyeInHand: flange_T_cam. EyeToHand: base_T_cam.
  Eigen::Isometry3d camera = Eigen::Isometry3d::Identity();
  // Where the gripper grasps the part, in the part's model frame.
  Eigen::Isometry3d part_T_grasp = Eigen::Isometry3d::Identity();

  // Empty when valid; else names the field (rotation not orthonormal, NaN, ...).
  std::string validate() const;
};

// A pose as x, y, z [mm] and rx, ry, rz [deg] in the euler.hpp convention.
struct PoseXYZ {
  Eigen::Vector3d position_mm = Eigen::Vector3d::Zero();
  EulerXYZ rotation;
};

Eigen::Isometry3d pose_to_isometry(const PoseXYZ& pose) noexcept;
PoseXYZ isometry_to_pose(const Eigen::Isometry3d& t) noexcept;

class PickTransform {
 public:
  // Throws std::invalid_argument with validate()'s message.
  explicit PickTransform(const HandEyeCalibration& calibration);

  // cam_T_part: the part pose found by vision. base_T_flange: the robot pose at capture,
  // required for EyeInHand (nullopt returns nullopt there) and ignored for EyeToHand.
  std::optional<Eigen::Isometry3d> base_T_pick(
      const Eigen::Isometry3d& cam_T_part, const std::optional<Eigen::Isometry3d>& base_T_flange = {}) const noexcept;

  // The same, as the float pose the robot link publishes.
  std::optional<PickPose> pick_pose(const Eigen::Isometry3d& cam_T_part,
                                    const std::optional<Eigen::Isometry3d>& base_T_flange = {}) const noexcept;

 private:
  HandEyeCalibration calibration_;
};

}  // namespace mfcd::motion
