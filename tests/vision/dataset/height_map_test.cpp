// The height-map rasteriser against the obviously right twin: a vertical ray through each
// cell centre intersected with every triangle.
#include "vision/dataset/height_map.hpp"
#include "vision/dataset/resting_poses.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

using namespace mfcd::vision;

namespace {

cv::Matx33d random_rotation(std::mt19937& rng) {
  std::normal_distribution<double> n;
  cv::Vec4d q(n(rng), n(rng), n(rng), n(rng));
  q /= cv::norm(q);
  const double w = q[0], x = q[1], y = q[2], z = q[3];
  return {1 - 2 * (y * y + z * z), 2 * (x * y - w * z),     2 * (x * z + w * y),
          2 * (x * y + w * z),     1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
          2 * (x * z - w * y),     2 * (y * z + w * x),     1 - 2 * (x * x + y * y)};
}

// Heights (floor_z - z) where the vertical line through (x, y) meets the mesh.
std::vector<double> ray_heights(const Mesh& m, const cv::Matx33d& R, const cv::Vec3d& t, double floor_z, double x,
                                double y) {
  std::vector<double> hits;
  for (const auto& tri : m.triangles) {
    cv::Vec3d p[3];
    for (int k = 0; k < 3; ++k) p[k] = R * cv::Vec3d(m.vertices[tri[static_cast<size_t>(k)]]) + t;
    const double det = (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[2][0] - p[0][0]) * (p[1][1] - p[0][1]);
    if (std::abs(det) < 1e-12) continue;
    const double l1 = ((x - p[0][0]) * (p[2][1] - p[0][1]) - (p[2][0] - p[0][0]) * (y - p[0][1])) / det;
    const double l2 = ((p[1][0] - p[0][0]) * (y - p[0][1]) - (x - p[0][0]) * (p[1][1] - p[0][1])) / det;
    if (l1 < 0 || l2 < 0 || l1 + l2 > 1) continue;
    hits.push_back(floor_z - ((1 - l1 - l2) * p[0][2] + l1 * p[1][2] + l2 * p[2][2]));
  }
  return hits;
}

}  // namespace

TEST(HeightMap, TopAndBottomMatchVerticalRaysOnRandomPoses) {
  std::mt19937 rng(7);
  const Mesh shapes[3] = {make_box(30, 20, 12), make_cylinder(10, 25, 24), make_uv_sphere(9, 16, 8)};
  const double floor_z = 300, cell = 0.5;
  for (int trial = 0; trial < 6; ++trial) {
    const Mesh& m = shapes[trial % 3];
    const cv::Matx33d R = random_rotation(rng);
    const cv::Vec3d t(std::uniform_real_distribution<double>(-3, 3)(rng), 1.3, 280);
    HeightMap top(-25, -25, 100, 100, cell, floor_z, -std::numeric_limits<float>::infinity());
    HeightMap bottom(-25, -25, 100, 100, cell, floor_z, std::numeric_limits<float>::infinity());
    top.raise_to_top(m, R, t);
    bottom.lower_to_bottom(m, R, t);
    int compared = 0, interior = 0, off = 0;
    for (int r = 0; r < 100; ++r)
      for (int c = 0; c < 100; ++c) {
        const cv::Point2d p = top.cell_centre(c, r);
        const auto hits = ray_heights(m, R, t, floor_z, p.x, p.y);
        if (hits.empty()) continue;
        const double hi = *std::max_element(hits.begin(), hits.end());
        const double lo = *std::min_element(hits.begin(), hits.end());
        ++compared;
        // Conservative: the map never reports the top lower or the bottom higher than the
        // surface at the cell centre (edge samples may only widen the range).
        ASSERT_GE(top.heights()(r, c), hi - 1e-4) << "trial " << trial << " cell " << c << "," << r;
        ASSERT_LE(bottom.heights()(r, c), lo + 1e-4) << "trial " << trial << " cell " << c << "," << r;
        // It never exceeds the surface anywhere in the cell: bounded by rays through the
        // cell's corners and edge midpoints too (ridges crossing a cell between samples
        // rise a little above them). Cells on the silhouette are left out.
        double cell_hi = hi, cell_lo = lo;
        bool covered = true;
        for (int dy = -1; dy <= 1 && covered; ++dy)
          for (int dx = -1; dx <= 1 && covered; ++dx) {
            const auto h = ray_heights(m, R, t, floor_z, p.x + dx * cell / 2, p.y + dy * cell / 2);
            covered = !h.empty();
            if (covered) {
              cell_hi = std::max(cell_hi, *std::max_element(h.begin(), h.end()));
              cell_lo = std::min(cell_lo, *std::min_element(h.begin(), h.end()));
            }
          }
        if (covered) {
          ++interior;
          off += top.heights()(r, c) > cell_hi + 0.3 || bottom.heights()(r, c) < cell_lo - 0.3;
        }
      }
    EXPECT_GT(compared, 200) << "trial " << trial;
    EXPECT_LE(off, interior / 50) << "trial " << trial << ": " << off << " of " << interior << " cells";
  }
}

TEST(HeightMap, ThinVerticalWallIsNotMissed) {
  // A 0.2 mm thick wall seen edge-on covers no cell centre; its edges still mark the cells.
  const Mesh wall = make_box(0.2, 20, 10);
  HeightMap top(-10, -10, 40, 40, 0.5, 300, 0.f);
  top.raise_to_top(wall, cv::Matx33d::eye(), {0.1, 0, 295});
  EXPECT_NEAR(top.at(0.1, 0, -1), 10.0, 1e-4);
  EXPECT_NEAR(top.at(0.1, 9, -1), 10.0, 1e-4);
  EXPECT_EQ(top.at(5, 0, -1), 0.f);
}
