// The second look's decision and geometry (daemon/look_planner.hpp): when a first look asks for a
// second, and the flange pose and camera motion, checked against explicit 4x4 products.
#include "daemon/look_planner.hpp"

#include <gtest/gtest.h>

#include "plc_test_client.hpp"

using namespace mfcd::daemon;
using mfcd::daemon::test::pose_of;

namespace {

CycleResult first_look(std::initializer_list<std::pair<float, bool>> candidates, int chosen) {
  CycleResult r;
  for (const auto& [score, ambiguous] : candidates) {
    CandidateOut& c = r.candidates[static_cast<std::size_t>(r.candidate_count++)];
    c.score = score;
    c.ambiguous = ambiguous;
  }
  r.chosen = chosen;
  return r;
}

Eigen::Isometry3d to_isometry(const mfcd::vision::RigidTransform& m) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) T.linear()(r, k) = m.R(r, k);
    T.translation()(r) = m.t[r];
  }
  return T;
}

}  // namespace

TEST(LookPlanner, AlwaysLooksAtTheChosenPickOrTheBestScored) {
  const mfcd::motion::PickChoiceConfig pick;
  const CycleResult r = first_look({{0.2f, false}, {0.7f, false}, {0.4f, true}}, 2);
  EXPECT_EQ(decide_look(SecondLookWhen::Always, r, pick).reason, LookReason::Always);
  EXPECT_EQ(decide_look(SecondLookWhen::Always, r, pick).candidate, 2);
  const CycleResult none = first_look({{0.2f, false}, {0.7f, false}}, -1);
  EXPECT_EQ(decide_look(SecondLookWhen::Always, none, pick).candidate, 1);
  EXPECT_EQ(decide_look(SecondLookWhen::Off, r, pick).reason, LookReason::None);
}

TEST(LookPlanner, UnsureLooksOnlyWhereThePickWasWithheldForDoubt) {
  mfcd::motion::PickChoiceConfig pick;
  pick.min_score = 0.3f;
  pick.skip_ambiguous = true;
  // A pick was chosen: no look.
  EXPECT_EQ(decide_look(SecondLookWhen::Unsure, first_look({{0.6f, false}}, 0), pick).reason, LookReason::None);
  // The best scored is ambiguous.
  LookDecision d = decide_look(SecondLookWhen::Unsure, first_look({{0.1f, false}, {0.6f, true}}, -1), pick);
  EXPECT_EQ(d.reason, LookReason::Ambiguous);
  EXPECT_EQ(d.candidate, 1);
  // The best scored is below min_score.
  d = decide_look(SecondLookWhen::Unsure, first_look({{0.25f, false}, {0.1f, false}}, -1), pick);
  EXPECT_EQ(d.reason, LookReason::LowScore);
  EXPECT_EQ(d.candidate, 0);
  // Withheld for something a second view does not change (e.g. grasp visibility): no look.
  EXPECT_EQ(decide_look(SecondLookWhen::Unsure, first_look({{0.8f, false}}, -1), pick).reason, LookReason::None);
  // Nothing found, a failed cycle, a count-only job: no look.
  EXPECT_EQ(decide_look(SecondLookWhen::Always, first_look({}, -1), pick).reason, LookReason::None);
  CycleResult failed = first_look({{0.1f, true}}, -1);
  failed.error = CycleError::Vision;
  EXPECT_EQ(decide_look(SecondLookWhen::Always, failed, pick).reason, LookReason::None);
  CycleResult count = first_look({{0.1f, true}}, -1);
  count.request.mode = 1;
  EXPECT_EQ(decide_look(SecondLookWhen::Always, count, pick).reason, LookReason::None);
}

TEST(LookPlanner, FlangePoseAndCameraMotionAreEachOthersInverse) {
  const Eigen::Isometry3d flange_T_camera = pose_of(10, -20, 150, 0, 0, 90);
  const Eigen::Isometry3d base_T_flange1 = pose_of(400, 50, 600, 180, 0, 30);
  const Eigen::Isometry3d base_T_flange2 = pose_of(455, 20, 590, 160, 12, 41);
  // The motion between two captures, by explicit products: camera 2 <- base <- camera 1.
  const Eigen::Isometry3d expect = (base_T_flange2 * flange_T_camera).inverse() * base_T_flange1 * flange_T_camera;
  const mfcd::vision::RigidTransform m = camera_motion(base_T_flange1, base_T_flange2, flange_T_camera);
  EXPECT_TRUE(to_isometry(m).isApprox(expect, 1e-12));
  // A point 300 mm in front of the first camera, seen from the second, is the same base point.
  const Eigen::Vector3d p1(12, -7, 300);
  const cv::Vec3d p2 = m.apply({p1.x(), p1.y(), p1.z()});
  const Eigen::Vector3d base1 = base_T_flange1 * flange_T_camera * p1;
  const Eigen::Vector3d base2 = base_T_flange2 * flange_T_camera * Eigen::Vector3d(p2[0], p2[1], p2[2]);
  EXPECT_LT((base1 - base2).norm(), 1e-9);
  // The flange pose for that motion is the second flange.
  EXPECT_TRUE(look_flange_pose(base_T_flange1, m, flange_T_camera).isApprox(base_T_flange2, 1e-12));
}
