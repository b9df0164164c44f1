// Out-of-plane view sampling: uniform coverage of the sphere, symmetry reduction, and camera
// rotations that look at the part centre.
#include "vision/templates/view_sampling.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

using namespace mfcd::vision;

namespace {
double angle(const cv::Vec3d& a, const cv::Vec3d& b) { return std::acos(std::clamp(a.dot(b), -1.0, 1.0)); }
double nearest(const std::vector<cv::Vec3d>& set, const cv::Vec3d& d) {
  double best = 10;
  for (const auto& s : set) best = std::min(best, angle(s, d));
  return best;
}
cv::Vec3d random_direction(std::mt19937& rng) {
  std::normal_distribution<double> n;
  return cv::normalize(cv::Vec3d(n(rng), n(rng), n(rng)));
}
}  // namespace

TEST(ViewSampling, FibonacciSphereCoversTheSphereUniformly) {
  const int K = 300;
  const auto dirs = fibonacci_sphere(K);
  ASSERT_EQ(dirs.size(), static_cast<size_t>(K));
  const double spacing = std::sqrt(4 * CV_PI / K);
  for (const auto& d : dirs) EXPECT_NEAR(cv::norm(d), 1.0, 1e-12);
  // Every sample has a neighbour about one spacing away and none much closer (no clumping).
  for (size_t i = 0; i < dirs.size(); ++i) {
    double nn = 10;
    for (size_t j = 0; j < dirs.size(); ++j)
      if (i != j) nn = std::min(nn, angle(dirs[i], dirs[j]));
    EXPECT_GT(nn, 0.6 * spacing) << i;
    EXPECT_LT(nn, 1.3 * spacing) << i;
  }
  // No direction is far from a sample: the coverage radius is about spacing / sqrt(2)..spacing.
  std::mt19937 rng(7);
  double worst = 0;
  for (int k = 0; k < 5000; ++k) worst = std::max(worst, nearest(dirs, random_direction(rng)));
  EXPECT_LT(worst, 0.85 * spacing);
  // Equal-area: each hemisphere and each octant holds its share within a few samples.
  int up = 0, octant = 0;
  for (const auto& d : dirs) up += d[2] > 0, octant += d[0] > 0 && d[1] > 0 && d[2] > 0;
  EXPECT_NEAR(up, K / 2, 2);
  EXPECT_NEAR(octant, K / 8, 5);
}

TEST(ViewSampling, DiscreteSymmetryKeepsOneWedgeThatStillCoversEverything) {
  const int K = 300;
  const PartSymmetry sym = PartSymmetry::parse("z:4");
  const auto kept = template_view_directions(K, sym);
  EXPECT_NEAR(static_cast<double>(kept.size()), K / 4.0, 6);
  // Any direction, turned into the wedge by a symmetry rotation, is near a kept view.
  std::mt19937 rng(3);
  const double spacing = std::sqrt(4 * CV_PI / K);
  const auto rotations = sym.discrete_rotations();
  ASSERT_EQ(rotations.size(), 4u);
  for (int k = 0; k < 2000; ++k) {
    const cv::Vec3d d = random_direction(rng);
    double best = 10;
    for (const auto& R : rotations) best = std::min(best, nearest(kept, R * d));
    EXPECT_LT(best, 1.0 * spacing);
  }
}

TEST(ViewSampling, ContinuousSymmetrySamplesOneMeridian) {
  const auto kept = template_view_directions(300, PartSymmetry::parse("z:inf"));
  EXPECT_GE(kept.size(), 16u);
  EXPECT_LE(kept.size(), 19u);
  for (const auto& d : kept) EXPECT_NEAR(d[1], 0.0, 1e-12);
  EXPECT_NEAR(kept.front()[2], 1.0, 1e-12);
  EXPECT_NEAR(kept.back()[2], -1.0, 1e-12);
}

TEST(ViewSampling, ViewRotationLooksAtThePartCentre) {
  std::mt19937 rng(11);
  std::vector<cv::Vec3d> dirs = {{0, 0, 1}, {0, 0, -1}, {1, 0, 0}};
  for (int k = 0; k < 200; ++k) dirs.push_back(random_direction(rng));
  for (const auto& d : dirs) {
    const cv::Matx33d R = view_rotation(d);
    const cv::Matx33d I = R * R.t();
    for (int i = 0; i < 9; ++i) EXPECT_NEAR(I.val[i], (i % 4 == 0) ? 1.0 : 0.0, 1e-12);
    EXPECT_NEAR(cv::determinant(R), 1.0, 1e-12);
    // The direction towards the camera maps to -z in the camera frame.
    const cv::Vec3d c = R * d;
    EXPECT_NEAR(c[2], -1.0, 1e-12);
  }
}

TEST(ViewSampling, SymmetryTextIsParsedOrRefused) {
  EXPECT_EQ(PartSymmetry::parse("none").kind, PartSymmetry::Kind::none);
  EXPECT_EQ(PartSymmetry::parse("z:2").order, 2);
  EXPECT_EQ(PartSymmetry::parse("z:inf").kind, PartSymmetry::Kind::continuous_z);
  EXPECT_EQ(PartSymmetry::parse("z:6").str(), "z:6");
  for (const char* bad : {"z", "z:", "z:0", "z:-2", "z:2x", "x:2", "yes"})
    EXPECT_THROW(PartSymmetry::parse(bad), std::invalid_argument) << bad;
}
