// Grasp-feature visibility from depth edges and their shadow sides, on drawn edge maps whose
// answer is known: a part's outline around the spot, discs lying on the part over the spot or
// beside it, a rod lying on the disc that covers the spot, and the part's own outline drawn with
// the wrong polarity. The rendered-scene check against the true masks is in
// tests/vision/pipeline (Pipeline.GraspVisibilityTellsACoveredHoleFromAFreeOne).
#include "vision/pose/grasp_visibility.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

using namespace mfcd::vision;

namespace {

constexpr double kPi = std::numbers::pi;

struct DrawnEdges {
  DepthEdges edges;
  cv::Mat1b own;
  DrawnEdges() {
    edges.edges = cv::Mat1b::zeros(240, 320);
    edges.direction = cv::Mat1f::zeros(240, 320);
    edges.shadow = cv::Mat1f::zeros(240, 320);
    own = cv::Mat1b::zeros(240, 320);
  }
  // One edge pixel whose shadow lies along `shadow_normal` (radians): the near surface is on the
  // other side. `own_turn`: also the part's own point there, its oriented tangent turned by this
  // from the edge's (0 = agrees); NaN = not the part's.
  void pixel(int x, int y, double shadow_normal, double own_turn = std::nan("")) {
    if (x < 0 || y < 0 || x >= edges.edges.cols || y >= edges.edges.rows) return;
    edges.edges(y, x) = 255;
    double tangent = std::fmod(shadow_normal + kPi / 2 + 2 * kPi, kPi);
    edges.direction(y, x) = static_cast<float>(tangent);
    edges.shadow(y, x) = static_cast<float>(std::fmod(shadow_normal + 4 * kPi, 2 * kPi));
    if (!std::isnan(own_turn)) {
      // Oriented tangent: its left normal (-sin, cos) points into the shadow.
      const double oriented = shadow_normal - kPi / 2 + own_turn;
      for (int dy = -2; dy <= 2; ++dy)
        for (int dx = -2; dx <= 2; ++dx) {
          const int px = x + dx, py = y + dy;
          if (px >= 0 && py >= 0 && px < own.cols && py < own.rows) own(py, px) = encode_own_direction(oriented);
        }
    }
  }
  // A circle's outline; near_inside: the disc is the nearer surface (its shadow falls outside).
  void circle(cv::Point2d c, double r, bool near_inside, double own_turn = std::nan("")) {
    const int n = static_cast<int>(2 * kPi * r * 3);
    for (int k = 0; k < n; ++k) {
      const double a = 2 * kPi * k / n;
      pixel(static_cast<int>(std::lround(c.x + r * std::cos(a))), static_cast<int>(std::lround(c.y + r * std::sin(a))),
            near_inside ? a : a + kPi, own_turn);
    }
  }
  // An axis-aligned rectangle's outline, the rectangle nearer than what is around it.
  void rectangle(int x0, int y0, int x1, int y1) {
    for (int x = x0; x <= x1; ++x) pixel(x, y0, -kPi / 2), pixel(x, y1, kPi / 2);
    for (int y = y0; y <= y1; ++y) pixel(x0, y, kPi), pixel(x1, y, 0);
  }
};

const cv::Point2d kSpot(160, 120);

TEST(GraspVisibility, PartOnTopSeesItsOwnOutlineAllRound) {
  DrawnEdges d;
  d.circle(kSpot, 60, true, 0.0);
  const GraspVisibility v = grasp_visibility(d.edges, d.own, kSpot, 10);
  EXPECT_GE(v.visible, 0.99);
  EXPECT_EQ(v.covered_votes, 0);
  EXPECT_GT(v.own_votes, 7 * 12);  // nearly every ray of the 7 sample points
}

TEST(GraspVisibility, ADiscLyingOverTheSpotCoversIt) {
  DrawnEdges d;
  d.circle(kSpot, 60, true, 0.0);
  d.circle(kSpot + cv::Point2d(3, -2), 25, true);
  const GraspVisibility v = grasp_visibility(d.edges, d.own, kSpot, 10);
  EXPECT_LE(v.visible, 0.05);
  EXPECT_GT(v.covered_votes, 7 * 12);
}

TEST(GraspVisibility, ARodLyingOnTheCoverDoesNotUncoverTheSpot) {
  // The rod crosses the cover next to the spot: rays into it step up onto the rod, across it and
  // down again, and go on to the cover's own outline, whose near side is the spot's.
  DrawnEdges d;
  d.circle(kSpot, 60, true, 0.0);
  d.circle(kSpot, 30, true);
  d.rectangle(100, 135, 220, 142);
  const GraspVisibility v = grasp_visibility(d.edges, d.own, kSpot, 8);
  EXPECT_LE(v.visible, 0.1);
}

TEST(GraspVisibility, ThingsLyingOnThePartBesideTheSpotLeaveItFree) {
  DrawnEdges d;
  d.circle(kSpot, 60, true, 0.0);
  d.circle(kSpot + cv::Point2d(35, 0), 14, true);  // a disc on the part, clear of the spot's rim
  d.rectangle(110, 70, 210, 78);                   // a rod across the part above the spot
  const GraspVisibility v = grasp_visibility(d.edges, d.own, kSpot, 10);
  EXPECT_GE(v.visible, 0.95);
}

TEST(GraspVisibility, TheOwnOutlineCountsOnlyWithItsPolarity) {
  // The same outline, but the part's points say the part is on its far side (the template turned
  // by 180 degrees there): the spot is then on something lying on top, not on the part.
  DrawnEdges d;
  d.circle(kSpot, 60, true, kPi);
  const GraspVisibility v = grasp_visibility(d.edges, d.own, kSpot, 10);
  EXPECT_EQ(v.own_votes, 0);
  EXPECT_LE(v.visible, 0.01);
  // Within the tolerance (30 degrees) it is the part's own outline again.
  DrawnEdges turned;
  turned.circle(kSpot, 60, true, 0.35);
  EXPECT_GE(grasp_visibility(turned.edges, turned.own, kSpot, 10).visible, 0.99);
}

TEST(GraspVisibility, NothingToTellWithoutShadowsOrEdges) {
  DrawnEdges d;
  d.circle(kSpot, 25, true);
  d.edges.shadow = cv::Mat1f();  // Canny edges: no shadow side
  EXPECT_EQ(grasp_visibility(d.edges, d.own, kSpot, 10).visible, 1.0);
  DrawnEdges empty;
  const GraspVisibility v = grasp_visibility(empty.edges, empty.own, kSpot, 10);
  EXPECT_EQ(v.visible, 1.0);
  EXPECT_EQ(v.own_votes + v.covered_votes, 0);
}

TEST(GraspVisibility, SamplePointsOutsideTheImageCountAsCovered) {
  DrawnEdges d;
  d.circle(cv::Point2d(5, 120), 60, true, 0.0);
  const GraspVisibility v = grasp_visibility(d.edges, d.own, cv::Point2d(2, 120), 10);
  EXPECT_GT(v.samples_outside, 0);
  EXPECT_LT(v.visible, 1.0);
}

// A pose whose model z axis points at the camera (a part lying with that side up), turned about
// the image's x axis by `tilt_deg`.
RigidPose facing(double tilt_deg) {
  const double t = tilt_deg * kPi / 180;
  const cv::Matx33d flip(1, 0, 0, 0, -1, 0, 0, 0, -1);  // model z -> camera -z (towards the camera)
  const cv::Matx33d tilt(1, 0, 0, 0, std::cos(t), -std::sin(t), 0, std::sin(t), std::cos(t));
  return RigidPose{tilt * flip, cv::Vec3d(0, 0, 300)};
}

TEST(GraspVisibility, FacesTheCameraWithinTheTilt) {
  GraspFeature f;
  f.approach = {0, 0, 1};
  f.max_tilt_deg = 45;
  EXPECT_TRUE(grasp_faces_camera(f, facing(0)));
  EXPECT_TRUE(grasp_faces_camera(f, facing(44)));
  EXPECT_FALSE(grasp_faces_camera(f, facing(46)));
  EXPECT_FALSE(grasp_faces_camera(f, facing(180)));  // lying on that side
  f.approach = {0, 0, -1};
  EXPECT_TRUE(grasp_faces_camera(f, facing(180)));
  f.approach = {0, 0, 0};  // any direction
  EXPECT_TRUE(grasp_faces_camera(f, facing(90)));
  // The line of sight, not the optical axis: a spot 300 mm off to the side is seen 45 degrees off.
  f.approach = {0, 0, 1};
  f.point_mm = {0, 0, 0};
  RigidPose off = facing(0);
  off.t_mm = {300, 0, 300};
  f.max_tilt_deg = 44;
  EXPECT_FALSE(grasp_faces_camera(f, off));
  f.max_tilt_deg = 46;
  EXPECT_TRUE(grasp_faces_camera(f, off));
}

TEST(GraspVisibility, FeatureValidationNamesTheReason) {
  GraspFeature f;
  EXPECT_EQ(f.validate(), "");
  f.radius_mm = 0;
  EXPECT_NE(f.validate().find("radius_mm"), std::string::npos);
  f.radius_mm = 4;
  f.max_tilt_deg = 200;
  EXPECT_NE(f.validate().find("max_tilt_deg"), std::string::npos);
  f.max_tilt_deg = 45;
  f.point_mm[1] = std::nan("");
  EXPECT_NE(f.validate().find("finite"), std::string::npos);
}

}  // namespace
