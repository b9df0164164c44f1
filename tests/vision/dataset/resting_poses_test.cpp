// Resting poses of shapes whose stable faces are known by hand.
#include "vision/dataset/resting_poses.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

using namespace mfcd::vision;

namespace {

// A parallelepiped: 10 x 10 base at z = 0, top face shifted by `shear` along x at z = h.
Mesh sheared_box(double shear, double h) {
  Mesh m;
  for (int k = 0; k < 8; ++k) {
    const double x = (k & 1) ? 10 : 0, y = (k & 2) ? 10 : 0, z = (k & 4) ? h : 0;
    m.vertices.emplace_back(static_cast<float>(x + (k & 4 ? shear : 0)), static_cast<float>(y), static_cast<float>(z));
  }
  // Quads as two triangles each, counter-clockwise seen from outside.
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    m.triangles.push_back({static_cast<uint32_t>(q[0]), static_cast<uint32_t>(q[1]), static_cast<uint32_t>(q[2])});
    m.triangles.push_back({static_cast<uint32_t>(q[0]), static_cast<uint32_t>(q[2]), static_cast<uint32_t>(q[3])});
  }
  return m;
}

}  // namespace

TEST(RestingPoses, CentreOfMassOfClosedShapes) {
  const cv::Vec3d c = centre_of_mass(make_box(40, 28, 18));
  EXPECT_LT(cv::norm(c), 1e-6);
  // Sheared box: the centre is the mean of the base and top centres.
  const cv::Vec3d s = centre_of_mass(sheared_box(30, 40));
  EXPECT_NEAR(s[0], 5 + 15, 1e-6);
  EXPECT_NEAR(s[1], 5, 1e-6);
  EXPECT_NEAR(s[2], 20, 1e-6);
}

TEST(RestingPoses, BoxRestsOnEachOfItsSixFaces) {
  const auto poses = stable_resting_poses(make_box(40, 28, 18));
  ASSERT_EQ(poses.size(), 6u);
  EXPECT_NEAR(poses[0].support_area_mm2, 40 * 28, 1e-3);
  EXPECT_NEAR(poses[5].support_area_mm2, 28 * 18, 1e-3);
  for (const auto& p : poses) {
    // R is a rotation taking the support face's outward normal to +z (down, into the floor).
    EXPECT_NEAR(cv::determinant(p.R), 1.0, 1e-9);
    const cv::Vec3d down = p.R * p.face_normal;
    EXPECT_NEAR(down[2], 1.0, 1e-9);
  }
}

TEST(RestingPoses, LeaningPrismDoesNotStandOnItsBase) {
  // The centre of mass (x = 20) lies beyond the 10 x 10 base (x in [0, 10]) and beyond the
  // top: neither is a resting face; the two long sheared sides and the two parallelogram
  // ends are.
  const auto poses = stable_resting_poses(sheared_box(30, 40));
  for (const auto& p : poses) EXPECT_LT(std::abs(p.face_normal[2]), 0.99) << "base or top reported stable";
  EXPECT_EQ(poses.size(), 4u);
  // A mild shear keeps the base stable.
  const auto mild = stable_resting_poses(sheared_box(4, 40));
  bool base = false;
  for (const auto& p : mild) base |= p.face_normal[2] < -0.99;
  EXPECT_TRUE(base);
}

TEST(RestingPoses, CylinderStandsOnEndsAndRollsOnItsSide) {
  const auto poses = stable_resting_poses(make_cylinder(15, 30, 32));
  // Two end caps plus one facet per side slice.
  EXPECT_EQ(poses.size(), 2u + 32u);
  EXPECT_NEAR(poses[0].support_area_mm2, 32 * 0.5 * 15 * 15 * std::sin(2 * std::numbers::pi / 32), 1e-2);
}

// The quasi-static landing weight: a box's faces, seen from its centre, subtend the analytic
// solid angle of a rectangle (4 asin(sin a sin b), a and b the half-angles of its sides) and
// together the whole sphere; so do a cylinder's caps and side facets.
TEST(RestingPoses, SolidAnglesOfTheFacesAreAnalyticAndCoverTheSphere) {
  const double sx = 40, sy = 28, sz = 18;
  const auto poses = stable_resting_poses(make_box(sx, sy, sz));
  ASSERT_EQ(poses.size(), 6u);
  double total = 0;
  for (const auto& p : poses) {
    // The face's two side lengths and its distance from the centre, by its normal's axis.
    const int axis = std::abs(p.face_normal[0]) > 0.5 ? 0 : std::abs(p.face_normal[1]) > 0.5 ? 1 : 2;
    const double size[3] = {sx, sy, sz};
    const double d = size[axis] / 2, s1 = size[(axis + 1) % 3], s2 = size[(axis + 2) % 3];
    const double expected = 4 * std::asin(std::sin(std::atan(s1 / 2 / d)) * std::sin(std::atan(s2 / 2 / d)));
    EXPECT_NEAR(p.solid_angle_sr, expected, 1e-9) << "axis " << axis;
    total += p.solid_angle_sr;
  }
  EXPECT_NEAR(total, 4 * std::numbers::pi, 1e-9);
  double cylinder = 0;
  for (const auto& p : stable_resting_poses(make_cylinder(15, 30, 32))) cylinder += p.solid_angle_sr;
  EXPECT_NEAR(cylinder, 4 * std::numbers::pi, 1e-6);
}
