// Coarse pose back-projection (paper Sec. 4.4-4.5): the part centre lands on the matched pixel
// at the view's distance over the scale, and placement_of inverts coarse_pose exactly.
#include "vision/pose/coarse_pose.hpp"

#include <gtest/gtest.h>

#include <opencv2/calib3d.hpp>

#include <random>

using namespace mfcd::vision;

namespace {
TemplateDatabase tiny_db() {
  TemplateDatabase db;
  db.distance_mm = 300;
  db.center_mm = {3, -2, 7};
  std::mt19937 rng(5);
  std::normal_distribution<double> n;
  for (int i = 0; i < 10; ++i) {
    TemplateView v;
    cv::Rodrigues(cv::Vec3d(n(rng), n(rng), n(rng)), v.R_m2c);
    v.t_m2c_mm = cv::Vec3d(0, 0, db.distance_mm) - v.R_m2c * db.center_mm;
    db.views.push_back(v);
  }
  return db;
}
}  // namespace

TEST(CoarsePose, BackProjectionRoundTrips) {
  const TemplateDatabase db = tiny_db();
  PinholeCamera cam;
  cam.K = cv::Matx33d(1100, 0, 320, 0, 1100, 240, 0, 0, 1);
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int k = 0; k < 500; ++k) {
    TemplatePlacement p{k % 10, u(rng) * CV_PI, 1.0 + 0.2 * u(rng), {320 + 300 * u(rng), 240 + 220 * u(rng)}};
    const RigidPose pose = coarse_pose(db, p, cam);
    // Rotation stays a rotation.
    EXPECT_NEAR(cv::determinant(pose.R), 1.0, 1e-9);
    // The part centre projects onto the matched pixel, at distance / scale from the lens.
    const cv::Vec3d c = pose.R * db.center_mm + pose.t_mm;
    const cv::Point2d px = cam.project(c);
    EXPECT_NEAR(px.x, p.origin_px.x, 1e-6);
    EXPECT_NEAR(px.y, p.origin_px.y, 1e-6);
    EXPECT_NEAR(cv::norm(c), db.distance_mm / p.scale, 1e-6);
    // And the placement is recovered.
    const TemplatePlacement back = placement_of(db, p.view, pose, cam);
    EXPECT_NEAR(std::remainder(back.angle_rad - p.angle_rad, 2 * CV_PI), 0.0, 1e-9);
    EXPECT_NEAR(back.scale, p.scale, 1e-9);
    EXPECT_NEAR(back.origin_px.x, p.origin_px.x, 1e-6);
  }
  // On the optical axis with no in-plane turn the pose is the view's own.
  const RigidPose on_axis = coarse_pose(db, {3, 0.0, 1.0, {320, 240}}, cam);
  for (int i = 0; i < 9; ++i) EXPECT_NEAR(on_axis.R.val[i], db.views[3].R_m2c.val[i], 1e-12);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(on_axis.t_mm[i], db.views[3].t_m2c_mm[i], 1e-9);
}

TEST(CoarsePose, BadPlacementIsRefused) {
  const TemplateDatabase db = tiny_db();
  PinholeCamera cam;
  EXPECT_THROW(coarse_pose(db, {10, 0, 1, {0, 0}}, cam), std::out_of_range);
  EXPECT_THROW(coarse_pose(db, {0, 0, 0, {0, 0}}, cam), std::invalid_argument);
}
