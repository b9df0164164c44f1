#include "motion/pick_transform.hpp"

#include <gtest/gtest.h>

#include <random>

using namespace mfcd::motion;

namespace {
Eigen::Isometry3d random_isometry(std::mt19937& rng) {
  std::uniform_real_distribution<double> angle(-180.0, 180.0), mm(-800.0, 800.0);
  return pose_to_isometry({Eigen::Vector3d(mm(rng), mm(rng), mm(rng)), {angle(rng), angle(rng) / 2, angle(rng)}});
}

// Slow twin: plain 4x4 homogeneous matrices.
Eigen::Matrix4d h(const Eigen::Isometry3d& t) { return t.matrix(); }
}  // namespace

TEST(PickTransform, EyeToHandHandComputed) {
  // Camera 1 m above the base origin looking straight down (camera Z = -base Z, X = base X).
  HandEyeCalibration cal;
  cal.setup = HandEyeSetup::EyeToHand;
  cal.camera = pose_to_isometry({Eigen::Vector3d(0, 0, 1000), {180, 0, 0}});
  const PickTransform transform(cal);
  // Part 800 mm in front of the camera, 50 mm along camera X and 20 mm along camera Y,
  // rotated 30 deg about the camera axis.
  const Eigen::Isometry3d cam_T_part = pose_to_isometry({Eigen::Vector3d(50, 20, 800), {0, 0, 30}});
  const auto pick = transform.pick_pose(cam_T_part);
  ASSERT_TRUE(pick);
  EXPECT_NEAR(pick->x_mm, 50.0, 1e-4);
  EXPECT_NEAR(pick->y_mm, -20.0, 1e-4);
  EXPECT_NEAR(pick->z_mm, 200.0, 1e-4);
  // Rx(180)*Rz(30) = Rz(-30)*Rx(180): rx 180, ry 0, rz -30.
  EXPECT_NEAR(std::abs(pick->rx_deg), 180.0, 1e-4);
  EXPECT_NEAR(pick->ry_deg, 0.0, 1e-4);
  EXPECT_NEAR(pick->rz_deg, -30.0, 1e-4);
}

TEST(PickTransform, EyeInHandEqualsEyeToHandWithTheSameCameraPose) {
  std::mt19937 rng(5);
  for (int i = 0; i < 1000; ++i) {
    const Eigen::Isometry3d base_T_flange = random_isometry(rng);
    const Eigen::Isometry3d flange_T_cam = random_isometry(rng);
    const Eigen::Isometry3d cam_T_part = random_isometry(rng);
    const Eigen::Isometry3d part_T_grasp = random_isometry(rng);
    HandEyeCalibration in_hand{HandEyeSetup::EyeInHand, flange_T_cam, part_T_grasp};
    HandEyeCalibration to_hand{HandEyeSetup::EyeToHand, base_T_flange * flange_T_cam, part_T_grasp};
    const auto a = PickTransform(in_hand).base_T_pick(cam_T_part, base_T_flange);
    const auto b = PickTransform(to_hand).base_T_pick(cam_T_part);
    ASSERT_TRUE(a && b);
    const Eigen::Matrix4d want = h(base_T_flange) * h(flange_T_cam) * h(cam_T_part) * h(part_T_grasp);
    ASSERT_TRUE(a->matrix().isApprox(want, 1e-9));
    ASSERT_TRUE(b->matrix().isApprox(want, 1e-9));
    // And the float pose describes the same transform.
    const auto pose = PickTransform(to_hand).pick_pose(cam_T_part);
    ASSERT_TRUE(pose);
    const Eigen::Isometry3d back = pose_to_isometry(
        {Eigen::Vector3d(pose->x_mm, pose->y_mm, pose->z_mm), {pose->rx_deg, pose->ry_deg, pose->rz_deg}});
    ASSERT_TRUE(back.translation().isApprox(want.block<3, 1>(0, 3), 1e-5));
    ASSERT_TRUE(back.linear().isApprox(want.block<3, 3>(0, 0), 1e-5));
  }
}

TEST(PickTransform, EyeInHandNeedsTheFlangePose) {
  HandEyeCalibration cal;
  cal.setup = HandEyeSetup::EyeInHand;
  EXPECT_FALSE(PickTransform(cal).base_T_pick(Eigen::Isometry3d::Identity()));
}

TEST(PickTransform, BadCalibrationIsNamed) {
  HandEyeCalibration cal;
  cal.camera.linear() << 1, 0, 0, 0, 2, 0, 0, 0, 1;
  EXPECT_NE(cal.validate().find("base_T_cam"), std::string::npos);
  EXPECT_THROW(PickTransform{cal}, std::invalid_argument);
  cal.setup = HandEyeSetup::EyeInHand;
  EXPECT_NE(cal.validate().find("flange_T_cam"), std::string::npos);
  cal = {};
  cal.part_T_grasp.translation().x() = std::nan("");
  EXPECT_NE(cal.validate().find("part_T_grasp: contains NaN"), std::string::npos);
  cal = {};
  cal.camera.linear() = -Eigen::Matrix3d::Identity();  // a reflection, det -1
  EXPECT_NE(cal.validate().find("not a proper"), std::string::npos);
}
