#include "motion/pick_transform.hpp"

#include <stdexcept>

namespace mfcd::motion {

namespace {
std::string check_isometry(const Eigen::Isometry3d& t, const char* name) {
  if (!t.matrix().allFinite()) return std::string("hand-eye ") + name + ": contains NaN or infinity";
  const Eigen::Matrix3d r = t.linear();
  if (!(r.transpose() * r).isApprox(Eigen::Matrix3d::Identity(), 1e-6) || r.determinant() < 0.0)
    return std::string("hand-eye ") + name + ": rotation is not a proper orthonormal matrix";
  return {};
}
}  // namespace

std::string HandEyeCalibration::validate() const {
  if (std::string e = check_isometry(camera, setup == HandEyeSetup::EyeInHand ? "flange_T_cam" : "base_T_cam");
      !e.empty())
    return e;
  return check_isometry(part_T_grasp, "part_T_grasp");
}

Eigen::Isometry3d pose_to_isometry(const PoseXYZ& pose) noexcept {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = euler_to_rotation(pose.rotation);
  t.translation() = pose.position_mm;
  return t;
}

PoseXYZ isometry_to_pose(const Eigen::Isometry3d& t) noexcept {
  return {t.translation(), rotation_to_euler(t.linear())};
}

PickTransform::PickTransform(const HandEyeCalibration& calibration) : calibration_(calibration) {
  if (std::string e = calibration.validate(); !e.empty()) throw std::invalid_argument(e);
}

std::optional<Eigen::Isometry3d> PickTransform::base_T_pick(
    const Eigen::Isometry3d& cam_T_part, const std::optional<Eigen::Isometry3d>& base_T_flange) const noexcept {
  Eigen::Isometry3d base_T_cam;
  if (calibration_.setup == HandEyeSetup::EyeInHand) {
    if (!base_T_flange) return std::nullopt;
    base_T_cam = *base_T_flange * calibration_.camera;
  } else {
    base_T_cam = calibration_.camera;
  }
  return base_T_cam * cam_T_part * calibration_.part_T_grasp;
}

std::optional<PickPose> PickTransform::pick_pose(const Eigen::Isometry3d& cam_T_part,
                                                 const std::optional<Eigen::Isometry3d>& base_T_flange) const noexcept {
  const auto t = base_T_pick(cam_T_part, base_T_flange);
  if (!t) return std::nullopt;
  const PoseXYZ p = isometry_to_pose(*t);
  return PickPose{static_cast<float>(p.position_mm.x()), static_cast<float>(p.position_mm.y()),
                  static_cast<float>(p.position_mm.z()), static_cast<float>(p.rotation.rx_deg),
                  static_cast<float>(p.rotation.ry_deg), static_cast<float>(p.rotation.rz_deg)};
}

}  // namespace mfcd::motion
