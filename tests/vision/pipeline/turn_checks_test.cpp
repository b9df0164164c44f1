// The pipeline's turn checks are made from the turns mfc-teach stored in the database
// (TemplateDatabase::turns), not found again from the mesh at load.
#include "vision/pipeline/turn_checks.hpp"
#include "vision/templates/template_teacher.hpp"

#include "vision/pose/rigid_transform.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <optional>

using namespace mfcd::vision;

namespace {

// A box taught with few views (the turn checks' flags are per view).
const TemplateDatabase& box_db() {
  static const TemplateDatabase db = [] {
    TeachParams p;
    p.sphere_samples = 24;
    p.threads = 2;
    p.edge_offset_profiles = false;
    return teach_templates(make_box(40, 30, 20),
                           load_camera_config(std::filesystem::path(MFC_SOURCE_DIR) / "config/camera-sim.yaml"), "box",
                           7, p);
  }();
  return db;
}

MeshTurn turn_of(MeshTurn::Kind kind, const cv::Matx33d& R, const cv::Vec3d& pivot) {
  MeshTurn t;
  t.kind = kind;
  t.R = R;
  t.pivot_mm = pivot;
  return t;
}

}  // namespace

TEST(TurnChecks, ComeFromTheTurnsStoredInTheDatabase) {
  TemplateDatabase db = box_db();
  // The box is D2: its half turns are symmetries, nothing is left to check.
  EXPECT_TRUE(detail::mesh_turns(db).empty());
  // Turns written into the database are what the checks use, in order, with their pivots.
  const cv::Matx33d quarter(0, -1, 0, 1, 0, 0, 0, 0, 1), over(1, 0, 0, 0, -1, 0, 0, 0, -1);
  db.turns.alternatives = {turn_of(MeshTurn::Kind::near_symmetry, quarter, {1, 2, 3}),
                           turn_of(MeshTurn::Kind::turn_over, over, {0, 0, 0})};
  const std::vector<detail::PoseTurn> turns = detail::mesh_turns(db);
  ASSERT_EQ(turns.size(), 2u);
  EXPECT_EQ(turns[0].S, quarter);
  EXPECT_EQ(turns[0].pivot_mm, cv::Vec3d(1, 2, 3));
  EXPECT_EQ(turns[1].S, over);
  // A near-symmetry is screened and carries, per view and point, the points its twin lacks: a
  // 40 x 30 box turned a quarter about a pivot off its axis lands partly in air.
  EXPECT_TRUE(turns[0].screen);
  ASSERT_EQ(turns[0].differs.size(), db.views.size());
  ASSERT_EQ(turns[0].differs_turned.size(), db.views.size());  // a quarter turn is not its own inverse
  size_t flagged = 0, points = 0;
  for (size_t v = 0; v < db.views.size(); ++v) {
    ASSERT_EQ(turns[0].differs[v].size(), db.views[v].points.size());
    for (uint8_t f : turns[0].differs[v]) flagged += f;
    points += db.views[v].points.size();
  }
  EXPECT_GT(flagged, 0u);
  EXPECT_LT(flagged, points);
  // A turn over changes most edges: compared whole, fitted, no flags.
  EXPECT_FALSE(turns[1].screen);
  EXPECT_TRUE(turns[1].differs.empty());
  EXPECT_EQ(turns[1].flags_of_pose(0), nullptr);
}

// A plate's normal comes from the mesh: the box's 2-fold axis along its least extent (20 mm, z),
// not a declared symmetry; its plate turns are +-15 degrees about it, judged by rank.
TEST(TurnChecks, PlateAxisIsTheTwoFoldAxisAlongThePartsLeastExtent) {
  TemplateDatabase db = box_db();
  ASSERT_EQ(db.symmetry.str(), "none");  // nothing declared
  const std::optional<cv::Vec3d> axis = detail::plate_axis(db);
  ASSERT_TRUE(axis.has_value());
  EXPECT_NEAR(std::abs((*axis)[2]), 1.0, 1e-3) << *axis;
  const std::vector<detail::PoseTurn> turns = detail::plate_turns(db);
  ASSERT_EQ(turns.size(), 2u);
  for (const detail::PoseTurn& t : turns) {
    EXPECT_TRUE(t.by_rank);
    EXPECT_NEAR(rotation_angle(t.S) * 180 / CV_PI, detail::kPlateTurnDeg, 1e-6);
    EXPECT_LT(cv::norm(t.S * *axis - *axis), 1e-9);  // about the axis
  }
  // A part whose 2-fold axis is not its thinnest (the symmetry about x only) is no plate.
  db.turns.symmetries.erase(std::remove_if(db.turns.symmetries.begin(), db.turns.symmetries.end(),
                                           [](const MeshTurn& s) { return std::abs(s.axis[0]) < 0.9; }),
                            db.turns.symmetries.end());
  ASSERT_EQ(db.turns.symmetries.size(), 1u);
  EXPECT_FALSE(detail::plate_axis(db).has_value());
  EXPECT_TRUE(detail::plate_turns(db).empty());
}
