// SymmetryGroup: the group its symmetries generate, and the angle between two orientations over
// it against a brute-force twin (every group element, continuous axes sampled in 0.05 degree steps).
#include "vision/model/symmetry_group.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace mfcd::vision {
namespace {

cv::Matx33d turn(const cv::Vec3d& axis, double deg) {
  const cv::Vec3d k = axis / cv::norm(axis);
  const double th = deg * CV_PI / 180;
  const cv::Matx33d Kx(0, -k[2], k[1], k[2], 0, -k[0], -k[1], k[0], 0);
  return cv::Matx33d::eye() + std::sin(th) * Kx + (1 - std::cos(th)) * Kx * Kx;
}

double angle_deg(const cv::Matx33d& R) {
  return std::acos(std::clamp((cv::trace(R) - 1.0) / 2.0, -1.0, 1.0)) * 180 / CV_PI;
}

MeshTurn symmetry(const cv::Vec3d& axis, int order) {
  MeshTurn t;
  t.kind = MeshTurn::Kind::symmetry;
  t.axis = axis / cv::norm(axis);
  t.order = order;
  return t;
}

cv::Matx33d random_rotation(std::mt19937& rng) {
  std::normal_distribution<double> n;
  std::uniform_real_distribution<double> u(0, 180);
  return turn(cv::Vec3d(n(rng), n(rng), n(rng)), u(rng));
}

// The slow twin: every element, and every continuous turn in fine steps.
double brute_force_deg(const SymmetryGroup& g, const cv::Matx33d& Ra, const cv::Matx33d& Rb) {
  double best = 180;
  for (const cv::Matx33d& S : g.rotations()) {
    best = std::min(best, angle_deg(Ra.t() * Rb * S));
    for (const cv::Vec3d& axis : g.continuous_axes())
      for (int i = 0; i < 7200; ++i) best = std::min(best, angle_deg(Ra.t() * Rb * S * turn(axis, i * 0.05)));
  }
  return best;
}

TEST(SymmetryGroup, GeneratesTheGroupOfItsSymmetries) {
  EXPECT_EQ(SymmetryGroup().rotations().size(), 1u);
  MeshTurns box;  // a box: 2-fold about x, y and z, the group D2 of 4 rotations
  box.symmetries = {symmetry({1, 0, 0}, 2), symmetry({0, 1, 0}, 2), symmetry({0, 0, 1}, 2)};
  EXPECT_EQ(SymmetryGroup(box).rotations().size(), 4u);
  MeshTurns hex;  // a hex nut: 6-fold about z and 2-fold about x, D6 of 12
  hex.symmetries = {symmetry({0, 0, 1}, 6), symmetry({1, 0, 0}, 2)};
  EXPECT_EQ(SymmetryGroup(hex).rotations().size(), 12u);
  MeshTurns cube;  // a cube: 4-fold about x, y and z, the 24 rotations of the octahedral group
  cube.symmetries = {symmetry({1, 0, 0}, 4), symmetry({0, 1, 0}, 4), symmetry({0, 0, 1}, 4)};
  EXPECT_EQ(SymmetryGroup(cube).rotations().size(), 24u);
}

TEST(SymmetryGroup, AngleIsTheSmallestOverTheGroup) {
  MeshTurns gear;
  gear.symmetries = {symmetry({0, 0, 1}, 4)};
  const SymmetryGroup g(gear);
  const cv::Matx33d R = turn({1, 2, 3}, 40);
  EXPECT_NEAR(g.angle_deg(R, R * turn({0, 0, 1}, 90)), 0, 1e-6);
  EXPECT_NEAR(g.angle_deg(R, R * turn({0, 0, 1}, 30)), 30, 1e-6);
  EXPECT_NEAR(g.angle_deg(R, R * turn({0, 0, 1}, 60)), 30, 1e-6);
  EXPECT_NEAR(g.angle_deg(R, R * turn({1, 0, 0}, 25)), 25, 1e-6);
  EXPECT_NEAR(SymmetryGroup().angle_deg(R, R * turn({0, 0, 1}, 90)), 90, 1e-6);
  MeshTurns cup;  // round about z
  cup.symmetries = {symmetry({0, 0, 1}, 0)};
  const SymmetryGroup c(cup);
  EXPECT_NEAR(c.angle_deg(R, R * turn({0, 0, 1}, 77)), 0, 1e-6);
  EXPECT_NEAR(c.angle_deg(R, R * turn({0, 0, 1}, 77) * turn({1, 1, 0}, 20)), 20, 1e-6);
  EXPECT_NEAR(c.angle_deg(R, R * turn({1, 0, 0}, 180)), 180, 1e-4);  // a cup turned over (acos near -1)
}

TEST(SymmetryGroup, MatchesTheBruteForceTwinOnRandomOrientations) {
  std::mt19937 rng(7);
  std::vector<MeshTurns> parts(4);
  parts[0].symmetries = {symmetry({0, 0, 1}, 6), symmetry({1, 0, 0}, 2)};
  parts[1].symmetries = {symmetry({0, 0, 1}, 0)};
  parts[2].symmetries = {symmetry({0, 0, 1}, 0), symmetry({1, 0, 0}, 2)};  // a cylinder
  parts[3].symmetries = {symmetry({1, 1, 0}, 3)};
  for (const MeshTurns& p : parts) {
    const SymmetryGroup g(p);
    for (int i = 0; i < 20; ++i) {
      const cv::Matx33d Ra = random_rotation(rng), Rb = random_rotation(rng);
      EXPECT_NEAR(g.angle_deg(Ra, Rb), brute_force_deg(g, Ra, Rb), 0.03) << i;
    }
  }
}

}  // namespace
}  // namespace mfcd::vision
