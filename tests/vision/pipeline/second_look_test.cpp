// SecondLook (paper Sec. 4.5's second camera position): the suggested camera centres the part and
// turns about it by the configured tilt; fusing a second frame set from there ranks each fused
// candidate by both images, keeps one per part, scores it with the fused confidence model, and
// places a diamond standing on its rim nearer its true pose than the one view did, on every render.
#include "vision/pipeline/second_look.hpp"

#include "tests/vision/support/pose_errors.hpp"
#include "tests/vision/support/rim_diamonds.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdio>

using namespace mfcd::vision;
using mfcd::vision::testing::RimDiamonds;
using mfcd::vision::testing::rotation_error_deg;

namespace {

std::chrono::steady_clock::time_point far_deadline() {
  return std::chrono::steady_clock::now() + std::chrono::seconds(60);
}

}  // namespace

TEST(SecondLook, RefusesBadParameters) {
  RimDiamonds scene;
  SecondLookParams p;
  p.tilt_deg = 2;
  EXPECT_THROW(SecondLook(scene.cam, scene.config(), p), std::invalid_argument);
  p = {};
  p.same_part_fraction = 0;
  EXPECT_THROW(SecondLook(scene.cam, scene.config(), p), std::invalid_argument);
  PipelineConfig ocm = scene.config();
  ocm.cost = PipelineConfig::Cost::ocm;
  EXPECT_THROW(SecondLook(scene.cam, ocm), std::invalid_argument);
}

TEST(SecondLook, SuggestedCameraCentresThePartAndTurnsByTheTilt) {
  RimDiamonds scene;
  SecondLookParams p;
  p.tilt_deg = 30;
  SecondLook look(scene.cam, scene.config(), p);
  PoseCandidate c;
  c.obj_id = scene.db.obj_id;
  c.R_m2c = scene.truth(0).R;
  c.t_m2c_mm = scene.truth(0).t_mm;
  const cv::Vec3d centre = c.R_m2c * scene.db.center_mm + c.t_m2c_mm;
  const RigidTransform m = look.suggest_motion(c);
  EXPECT_LT(cv::norm(m.R * m.R.t() - cv::Matx33d::eye()), 1e-12);
  const cv::Vec3d seen = m.apply(centre);
  EXPECT_NEAR(seen[0], 0, 1e-9);  // on the second camera's optical axis
  EXPECT_NEAR(seen[1], 0, 1e-9);
  EXPECT_NEAR(seen[2], cv::norm(centre), 1e-9);  // at the same distance
  // The two cameras' lines of sight to the centre meet there at the tilt.
  const cv::Vec3d second_origin = m.inverse().t;
  const cv::Vec3d a = cv::normalize(-centre), b = cv::normalize(second_origin - centre);
  EXPECT_NEAR(std::acos(a.dot(b)) * 180 / CV_PI, 30.0, 1e-6);
}

TEST(SecondLook, TheFloorMovesWithTheCamera) {
  RimDiamonds scene;
  SecondLook look(scene.cam, scene.config());
  PoseCandidate c;
  c.obj_id = scene.db.obj_id;
  c.R_m2c = scene.truth(0).R;
  c.t_m2c_mm = scene.truth(0).t_mm;
  const RigidTransform m = look.suggest_motion(c);
  const BinFloor floor = scene.config().floor;
  const BinFloor moved = floor_after(floor, m);
  EXPECT_NO_THROW(moved.validate());
  // Points of the first camera's floor lie on the moved floor; a point above it stays above it.
  for (const cv::Vec3d& p : {cv::Vec3d(0, 0, 300), cv::Vec3d(80, -40, 300), cv::Vec3d(-120, 90, 300)})
    EXPECT_NEAR(moved.normal.dot(m.apply(p)), moved.distance_mm, 1e-9);
  EXPECT_LT(moved.normal.dot(m.apply(cv::Vec3d(10, 20, 290))), moved.distance_mm);
  EXPECT_FALSE(floor_after(BinFloor{}, m).known());
  // Seen from below, the floor is left unknown.
  const RigidTransform flipped{cv::Matx33d(1, 0, 0, 0, -1, 0, 0, 0, -1), cv::Vec3d(0, 0, 0)};
  EXPECT_FALSE(floor_after(floor, flipped).known());
}

TEST(SecondLook, PlacesADiamondOnItsRimNearerTheTruthThanOneView) {
  RimDiamonds scene;
  const TemplateDatabase& db = scene.db;
  SecondLook look(scene.cam, scene.config());
  int right_one = 0, right_fused = 0;
  double dt_one = 0, dr_one = 0, dt_fused = 0, dr_fused = 0;
  const int renders = 8;
  for (int k = 0; k < renders; ++k) {
    const RigidPose& truth = scene.truth(k);
    const cv::Vec3d centre = truth.R * db.center_mm + truth.t_mm;
    auto right = [&](const cv::Matx33d& R, const cv::Vec3d& t, double& dt, double& dr) {
      dt = cv::norm(R * db.center_mm + t - centre);
      dr = rotation_error_deg(R, truth.R, db.symmetry);
      return dt <= 5.0 && dr <= 10.0;
    };
    PipelineResult first;
    look.first().process(scene.render(k).frames, 0, far_deadline(), first);
    ASSERT_FALSE(first.candidates.empty()) << "render " << k;
    const RigidTransform motion = look.suggest_motion(first.candidates.front());
    SecondLookResult fused;
    look.fuse(first, scene.render(k, motion).frames, motion, 0, far_deadline(), fused);
    ASSERT_FALSE(fused.candidates.empty()) << "render " << k;
    EXPECT_FALSE(fused.degraded) << "render " << k;
    double dt1, dr1, dt2, dr2;
    right_one += right(first.candidates.front().R_m2c, first.candidates.front().t_m2c_mm, dt1, dr1);
    const SecondLookCandidate& best = fused.candidates.front();
    right_fused += right(best.R_m2c, best.t_m2c_mm, dt2, dr2);
    dt_one += dt1, dr_one += dr1, dt_fused += dt2, dr_fused += dr2;
    std::printf("render %d: one view %.2f mm %.2f deg, two views %.2f mm %.2f deg (ranks %.3f + %.3f, from view %d)\n",
                k, dt1, dr1, dt2, dr2, best.rank_first, best.rank_second, best.proposed_by);
    // The first camera's pick candidates: the same poses, scores and ranks, in the same order.
    PipelineResult picks;
    look.to_pipeline_result(fused, picks);
    ASSERT_EQ(picks.candidates.size(), fused.candidates.size());
    for (size_t i = 0; i < fused.candidates.size(); ++i) {
      const SecondLookCandidate& c = fused.candidates[i];
      EXPECT_DOUBLE_EQ(c.rank, c.rank_first + c.rank_second);
      // The fused score is the fused model's probability of the candidate's own measures.
      EXPECT_DOUBLE_EQ(c.score, SecondLookParams{}.confidence.probability(c.evidence()));
      EXPECT_EQ(c.evidence().alternative_margin, c.has_alternative ? c.rank - c.alternative_rank : 0.0);
      const PoseCandidate& p = picks.candidates[i];
      EXPECT_EQ(p.obj_id, c.obj_id);
      EXPECT_EQ(p.part, db.part_name);
      EXPECT_EQ(p.score, c.score);
      EXPECT_EQ(p.fit_rank, c.rank);
      EXPECT_EQ(cv::norm(p.t_m2c_mm - c.t_m2c_mm), 0.0);
      EXPECT_FALSE(p.ambiguous);
      // The projected part box holds the image of its centre.
      const cv::Vec3d centre_cam = c.R_m2c * db.center_mm + c.t_m2c_mm;
      const cv::Point2d u(scene.cam.camera.fx() * centre_cam[0] / centre_cam[2] + scene.cam.camera.cx(),
                          scene.cam.camera.fy() * centre_cam[1] / centre_cam[2] + scene.cam.camera.cy());
      EXPECT_TRUE(p.box.contains(u)) << "render " << k;
      if (i > 0) {
        EXPECT_LE(c.rank, fused.candidates[i - 1].rank);
      }
      for (size_t j = 0; j < i; ++j) {
        const SecondLookCandidate& o = fused.candidates[j];
        EXPECT_GE(cv::norm((c.R_m2c * db.center_mm + c.t_m2c_mm) - (o.R_m2c * db.center_mm + o.t_m2c_mm)),
                  0.25 * db.diameter_mm)
            << "one candidate per part";
      }
    }
  }
  std::printf(
      "right: one view %d, two views %d of %d; mean error one view %.2f mm %.2f deg, two views %.2f mm %.2f deg\n",
      right_one, right_fused, renders, dt_one / renders, dr_one / renders, dt_fused / renders, dr_fused / renders);
  EXPECT_EQ(right_fused, renders);
  EXPECT_LT(dt_fused, 0.75 * dt_one);
  EXPECT_LT(dr_fused, 0.75 * dr_one);
  // Past its deadline the fusion stops where it is and says so (the daemon reports the cycle
  // degraded from this flag).
  PipelineResult first;
  look.first().process(scene.render(0).frames, 0, far_deadline(), first);
  const RigidTransform motion = look.suggest_motion(first.candidates.front());
  SecondLookResult late;
  look.fuse(first, scene.render(0, motion).frames, motion, 0,
            std::chrono::steady_clock::now() - std::chrono::seconds(1), late);
  EXPECT_TRUE(late.degraded);
}
