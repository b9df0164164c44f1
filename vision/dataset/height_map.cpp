#include "vision/dataset/height_map.hpp"

#include <algorithm>
#include <cmath>

namespace mfcd::vision {

HeightMap::HeightMap(double x0_mm, double y0_mm, int cols, int rows, double cell_mm, double floor_z_mm, float initial)
    : x0_(x0_mm), y0_(y0_mm), cell_(cell_mm), floor_z_(floor_z_mm), h_(rows, cols, initial) {}

float HeightMap::at(double x_mm, double y_mm, float outside) const {
  const int c = static_cast<int>(std::floor((x_mm - x0_) / cell_));
  const int r = static_cast<int>(std::floor((y_mm - y0_) / cell_));
  if (c < 0 || r < 0 || c >= h_.cols || r >= h_.rows) return outside;
  return h_(r, c);
}

void HeightMap::raise_to_top(const Mesh& mesh, const cv::Matx33d& R, const cv::Vec3d& t) {
  rasterise(mesh, R, t, true);
}
void HeightMap::lower_to_bottom(const Mesh& mesh, const cv::Matx33d& R, const cv::Vec3d& t) {
  rasterise(mesh, R, t, false);
}

void HeightMap::rasterise(const Mesh& mesh, const cv::Matx33d& R, const cv::Vec3d& t, bool top) {
  // Vertices in grid units (column, row) and height.
  std::vector<cv::Vec3d> g(mesh.vertices.size());
  for (size_t i = 0; i < g.size(); ++i) {
    const cv::Vec3d p = R * cv::Vec3d(mesh.vertices[i]) + t;
    g[i] = {(p[0] - x0_) / cell_, (p[1] - y0_) / cell_, floor_z_ - p[2]};
  }
  auto put = [&](int c, int r, double h) {
    if (c < 0 || r < 0 || c >= h_.cols || r >= h_.rows) return;
    float& cell = h_(r, c);
    const auto v = static_cast<float>(h);
    cell = top ? std::max(cell, v) : std::min(cell, v);
  };
  for (const auto& tri : mesh.triangles) {
    const cv::Vec3d& a = g[tri[0]];
    const cv::Vec3d& b = g[tri[1]];
    const cv::Vec3d& c = g[tri[2]];
    // Edges (and so vertices), sampled every half cell: covers triangles seen edge-on.
    for (const auto& [p, q] : {std::pair{a, b}, std::pair{b, c}, std::pair{c, a}}) {
      const double len = std::hypot(q[0] - p[0], q[1] - p[1]);
      const int steps = static_cast<int>(std::ceil(len * 2)) + 1;
      for (int s = 0; s <= steps; ++s) {
        const cv::Vec3d x = p + (q - p) * (static_cast<double>(s) / steps);
        put(static_cast<int>(std::floor(x[0])), static_cast<int>(std::floor(x[1])), x[2]);
      }
    }
    // Interior: cell centres inside the triangle, height interpolated barycentrically.
    const double det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
    if (std::abs(det) < 1e-12) continue;
    const int c0 = std::max(0, static_cast<int>(std::floor(std::min({a[0], b[0], c[0]}))));
    const int c1 = std::min(h_.cols - 1, static_cast<int>(std::ceil(std::max({a[0], b[0], c[0]}))));
    const int r0 = std::max(0, static_cast<int>(std::floor(std::min({a[1], b[1], c[1]}))));
    const int r1 = std::min(h_.rows - 1, static_cast<int>(std::ceil(std::max({a[1], b[1], c[1]}))));
    for (int r = r0; r <= r1; ++r)
      for (int col = c0; col <= c1; ++col) {
        const double px = col + 0.5, py = r + 0.5;
        const double l1 = ((px - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (py - a[1])) / det;
        const double l2 = ((b[0] - a[0]) * (py - a[1]) - (px - a[0]) * (b[1] - a[1])) / det;
        const double l0 = 1 - l1 - l2;
        if (l0 < -1e-9 || l1 < -1e-9 || l2 < -1e-9) continue;
        put(col, r, l0 * a[2] + l1 * b[2] + l2 * c[2]);
      }
  }
}

}  // namespace mfcd::vision
