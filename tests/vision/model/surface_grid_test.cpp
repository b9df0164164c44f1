// SurfaceGrid against its slow twin (distance_to_surface, every triangle visited), which is in
// turn checked against the analytic distance to a box's surface.
#include "vision/model/surface_grid.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

using namespace mfcd::vision;

namespace {

// Distance from p to the surface of the box [-h, h] (axis-aligned, centred on the origin).
double box_surface_distance(const cv::Vec3d& p, const cv::Vec3d& h) {
  const cv::Vec3d q(std::abs(p[0]) - h[0], std::abs(p[1]) - h[1], std::abs(p[2]) - h[2]);
  const cv::Vec3d outside(std::max(q[0], 0.0), std::max(q[1], 0.0), std::max(q[2], 0.0));
  const double inside = std::min(std::max({q[0], q[1], q[2]}), 0.0);
  return cv::norm(outside) + std::abs(inside);  // inside: distance to the nearest face
}

}  // namespace

TEST(SurfaceGrid, BruteForceDistanceIsTheBoxesAnalyticDistance) {
  const cv::Vec3d h(20, 12, 7);
  const Mesh box = make_box(2 * h[0], 2 * h[1], 2 * h[2]);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.3, 1.3);
  for (int i = 0; i < 2000; ++i) {
    const cv::Vec3d p(u(rng) * h[0], u(rng) * h[1], u(rng) * h[2]);
    ASSERT_NEAR(distance_to_surface(box, p), box_surface_distance(p, h), 1e-4) << p;
  }
}

// Inside the guaranteed bands (tolerance -/+ half a voxel diagonal) the grid answers as the exact
// distance does; points are drawn near the surface so that both answers occur often.
TEST(SurfaceGrid, AgreesWithTheExactDistanceOutsideHalfAVoxelDiagonal) {
  const double voxel = 0.25, tolerance = 0.5;
  const double slack = std::sqrt(3.0) / 2 * voxel;
  std::mt19937 rng(12);
  for (const Mesh& mesh : {make_box(30, 18, 9), make_cylinder(11, 16, 32), make_uv_sphere(9, 24, 12)}) {
    const SurfaceGrid grid(mesh, voxel, tolerance);
    std::uniform_int_distribution<size_t> vertex(0, mesh.vertices.size() - 1);
    std::uniform_real_distribution<double> u(-1, 1);
    int near = 0, far = 0;
    for (int i = 0; i < 4000; ++i) {
      // A vertex (or the midpoint of two) moved by up to 2 mm in any direction.
      const cv::Vec3f a = mesh.vertices[vertex(rng)], b = mesh.vertices[vertex(rng)];
      const cv::Vec3d base =
          i % 2 ? cv::Vec3d(a[0], a[1], a[2]) : 0.5 * cv::Vec3d(a[0] + b[0], a[1] + b[1], a[2] + b[2]);
      const cv::Vec3d p = base + 2.0 * cv::Vec3d(u(rng), u(rng), u(rng));
      const double d = distance_to_surface(mesh, p);
      if (d <= tolerance - slack) {
        ASSERT_TRUE(grid.near(p)) << p << " at " << d << " mm";
        ++near;
      } else if (d > tolerance + slack) {
        ASSERT_FALSE(grid.near(p)) << p << " at " << d << " mm";
        ++far;
      }
    }
    EXPECT_GT(near, 100);
    EXPECT_GT(far, 1000);
    EXPECT_FALSE(grid.near(cv::Vec3d(1000, 0, 0)));  // outside the grid
  }
}

TEST(SurfaceGrid, RefusesAnEmptyMeshAndNonPositiveSizes) {
  EXPECT_THROW(SurfaceGrid(Mesh{}, 0.25, 0.5), std::invalid_argument);
  const Mesh box = make_box(10, 10, 10);
  EXPECT_THROW(SurfaceGrid(box, 0, 0.5), std::invalid_argument);
  EXPECT_THROW(SurfaceGrid(box, 0.25, -1), std::invalid_argument);
}
