// BinFloor against a box, whose deepest point below a plane is known in closed form: the sum over
// its axes of the half side times the axis' share of the normal.
#include "vision/pose/bin_floor.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

using namespace mfcd::vision;

namespace {

Mesh box(double ax, double by, double cz) {
  Mesh m;
  for (int i = 0; i < 8; ++i)
    m.vertices.emplace_back(float((i & 1 ? 1 : -1) * ax), float((i & 2 ? 1 : -1) * by), float((i & 4 ? 1 : -1) * cz));
  // Twelve triangles are not needed by BinFloor; a few keep the mesh a valid triangle list.
  m.triangles = {{0, 1, 3}, {0, 3, 2}, {4, 6, 7}, {4, 7, 5}};
  return m;
}

RigidPose random_pose(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  const cv::Vec3d w(u(rng), u(rng), u(rng));
  cv::Matx33d R = cv::Matx33d::eye();
  const double th = cv::norm(w) * CV_PI;
  if (th > 1e-9) {
    const cv::Vec3d k = w / cv::norm(w);
    const cv::Matx33d K(0, -k[2], k[1], k[2], 0, -k[0], -k[1], k[0], 0);
    R = cv::Matx33d::eye() + std::sin(th) * K + (1 - std::cos(th)) * K * K;
  }
  return {R, {40 * u(rng), 30 * u(rng), 280 + 20 * u(rng)}};
}

BinFloor tilted_floor(std::mt19937& rng, double distance) {
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  BinFloor f;
  f.normal = cv::normalize(cv::Vec3d(u(rng), u(rng), 1));
  f.distance_mm = distance;
  return f;
}

}  // namespace

TEST(BinFloor, ReachBelowIsTheBoxFormula) {
  const double half[3] = {20, 12, 5};
  const Mesh m = box(half[0], half[1], half[2]);
  std::mt19937 rng(3);
  for (int i = 0; i < 200; ++i) {
    const RigidPose pose = random_pose(rng);
    const BinFloor floor = tilted_floor(rng, 290);
    const cv::Vec3d n_model = pose.R.t() * floor.normal;
    double expected = floor.normal.dot(pose.t_mm) - floor.distance_mm;
    for (int a = 0; a < 3; ++a) expected += half[a] * std::abs(n_model[a]);
    ASSERT_NEAR(floor.reach_below(m, pose), expected, 1e-4) << "pose " << i;
  }
}

TEST(BinFloor, BelowHonoursTheToleranceAndAnUnknownFloor) {
  const Mesh m = box(10, 10, 10);
  BinFloor floor;
  floor.distance_mm = 300;
  floor.tolerance_mm = 3;
  const RigidPose at{cv::Matx33d::eye(), {0, 0, 290}};  // deepest point at 300: on the floor
  EXPECT_FALSE(floor.below(m, at));
  EXPECT_FALSE(floor.below(m, {at.R, {0, 0, 292.9}}));
  EXPECT_TRUE(floor.below(m, {at.R, {0, 0, 293.1}}));
  floor.distance_mm = 0;  // not known
  EXPECT_FALSE(floor.below(m, {at.R, {0, 0, 1000}}));
}

// Onto puts the deepest point on the plane, keeps the rotation and the pivot's image point.
TEST(BinFloor, OntoRestsThePartOnThePlaneAlongTheLineOfSight) {
  const Mesh m = box(25, 15, 6);
  const cv::Vec3d pivot(3, -2, 1);
  std::mt19937 rng(5);
  for (int i = 0; i < 200; ++i) {
    const RigidPose pose = random_pose(rng);
    const BinFloor floor = tilted_floor(rng, 270 + 40 * std::uniform_real_distribution<double>(0, 1)(rng));
    const RigidPose moved = floor.onto(m, pose, pivot);
    EXPECT_NEAR(floor.reach_below(m, moved), 0.0, 1e-6) << "pose " << i;
    EXPECT_LE(cv::norm(moved.R - pose.R), 0.0);
    const cv::Vec3d a = pose.R * pivot + pose.t_mm, b = moved.R * pivot + moved.t_mm;
    EXPECT_NEAR(a[0] / a[2], b[0] / b[2], 1e-9);
    EXPECT_NEAR(a[1] / a[2], b[1] / b[2], 1e-9);
  }
  BinFloor unknown;
  const RigidPose pose{cv::Matx33d::eye(), {1, 2, 500}};
  EXPECT_EQ(unknown.onto(m, pose, pivot).t_mm, pose.t_mm);
}

// onto_if_below: a pose below the floor goes onto it, any other stays exactly as it was.
TEST(BinFloor, OntoIfBelowMovesOnlyPosesBelowTheFloor) {
  const Mesh m = box(25, 15, 6);
  const cv::Vec3d pivot(3, -2, 1);
  std::mt19937 rng(7);
  int moved_count = 0, kept_count = 0;
  for (int i = 0; i < 200; ++i) {
    const RigidPose pose = random_pose(rng);
    const BinFloor floor = tilted_floor(rng, 270 + 40 * std::uniform_real_distribution<double>(0, 1)(rng));
    const RigidPose out = floor.onto_if_below(m, pose, pivot);
    if (floor.below(m, pose)) {
      ++moved_count;
      const RigidPose onto = floor.onto(m, pose, pivot);
      EXPECT_EQ(out.t_mm, onto.t_mm) << "pose " << i;
      EXPECT_FALSE(floor.below(m, out)) << "pose " << i;
    } else {
      ++kept_count;
      EXPECT_EQ(out.t_mm, pose.t_mm) << "pose " << i;
    }
    EXPECT_LE(cv::norm(out.R - pose.R), 0.0);
  }
  EXPECT_GT(moved_count, 10);
  EXPECT_GT(kept_count, 10);
}

TEST(BinFloor, ValidateNamesWhatIsWrong) {
  auto message = [](const BinFloor& f) {
    try {
      f.validate();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  BinFloor f;
  EXPECT_EQ(message(f), "");  // not known: nothing to check
  f.distance_mm = -1;
  EXPECT_NE(message(f).find("distance_mm"), std::string::npos);
  f.distance_mm = 300;
  EXPECT_EQ(message(f), "");
  f.tolerance_mm = -0.5;
  EXPECT_NE(message(f).find("tolerance_mm"), std::string::npos);
  f.tolerance_mm = 3;
  f.normal = {0, 0, 1.01};
  EXPECT_NE(message(f).find("unit"), std::string::npos);
  f.normal = {0, 0, -1};
  EXPECT_NE(message(f).find("away from the camera"), std::string::npos);
}
