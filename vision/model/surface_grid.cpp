#include "vision/model/surface_grid.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace mfcd::vision {
namespace {

cv::Vec3d vec(const cv::Vec3f& v) { return {v[0], v[1], v[2]}; }

// Closest point of triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5: the
// Voronoi regions of the vertices, then the edges, then the face).
cv::Vec3d closest_on_triangle(const cv::Vec3d& p, const cv::Vec3d& a, const cv::Vec3d& b, const cv::Vec3d& c) {
  const cv::Vec3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const cv::Vec3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + ab * (d1 / (d1 - d3));
  const cv::Vec3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + ac * (d2 / (d2 - d6));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

}  // namespace

double distance_to_surface(const Mesh& mesh, const cv::Vec3d& p) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& t : mesh.triangles) {
    const cv::Vec3d q =
        closest_on_triangle(p, vec(mesh.vertices[t[0]]), vec(mesh.vertices[t[1]]), vec(mesh.vertices[t[2]]));
    best = std::min(best, cv::norm(p - q));
  }
  return best;
}

SurfaceGrid::SurfaceGrid(const Mesh& mesh, double voxel_mm, double tolerance_mm)
    : voxel_(voxel_mm), tolerance_(tolerance_mm) {
  if (mesh.vertices.empty() || mesh.triangles.empty()) throw std::invalid_argument("surface grid: empty mesh");
  if (!(voxel_mm > 0) || !(tolerance_mm > 0))
    throw std::invalid_argument("surface grid: voxel and tolerance must be > 0 mm");
  const cv::Vec3f lo = mesh.bbox_min(), hi = mesh.bbox_max();
  const double pad = tolerance_mm + voxel_mm;
  origin_ = vec(lo) - cv::Vec3d(pad, pad, pad);
  nx_ = static_cast<int>(std::ceil((hi[0] - lo[0] + 2 * pad) / voxel_mm)) + 1;
  ny_ = static_cast<int>(std::ceil((hi[1] - lo[1] + 2 * pad) / voxel_mm)) + 1;
  nz_ = static_cast<int>(std::ceil((hi[2] - lo[2] + 2 * pad) / voxel_mm)) + 1;
  marked_.assign(static_cast<size_t>(nx_) * ny_ * nz_, 0);
  // A voxel is marked when its centre lies within the tolerance of a triangle: each triangle
  // visits the voxels of its bounding box grown by the tolerance.
  const double reach = tolerance_mm + 1e-9;
  for (const auto& t : mesh.triangles) {
    const cv::Vec3d a = vec(mesh.vertices[t[0]]), b = vec(mesh.vertices[t[1]]), c = vec(mesh.vertices[t[2]]);
    // Voxels farther than the tolerance from the triangle's plane are skipped before the exact
    // test (a large flat face has a large bounding box but a thin slab of voxels near it).
    cv::Vec3d normal = (b - a).cross(c - a);
    const double area2 = cv::norm(normal);
    if (area2 > 0) normal /= area2;
    int lo_i[3], hi_i[3];
    for (int k = 0; k < 3; ++k) {
      const double mn = std::min({a[k], b[k], c[k]}) - reach, mx = std::max({a[k], b[k], c[k]}) + reach;
      lo_i[k] = std::max(0, static_cast<int>(std::floor((mn - origin_[k]) / voxel_mm - 0.5)));
      hi_i[k] = static_cast<int>(std::ceil((mx - origin_[k]) / voxel_mm - 0.5));
    }
    hi_i[0] = std::min(hi_i[0], nx_ - 1);
    hi_i[1] = std::min(hi_i[1], ny_ - 1);
    hi_i[2] = std::min(hi_i[2], nz_ - 1);
    for (int z = lo_i[2]; z <= hi_i[2]; ++z)
      for (int y = lo_i[1]; y <= hi_i[1]; ++y)
        for (int x = lo_i[0]; x <= hi_i[0]; ++x) {
          uint8_t& m = marked_[(static_cast<size_t>(z) * ny_ + y) * nx_ + x];
          if (m) continue;
          const cv::Vec3d centre = origin_ + cv::Vec3d(x + 0.5, y + 0.5, z + 0.5) * voxel_mm;
          if (area2 > 0 && std::abs(normal.dot(centre - a)) > reach) continue;
          if (cv::norm(centre - closest_on_triangle(centre, a, b, c)) <= reach) m = 1;
        }
  }
}

bool SurfaceGrid::near(const cv::Vec3d& p) const {
  const int x = static_cast<int>(std::floor((p[0] - origin_[0]) / voxel_));
  const int y = static_cast<int>(std::floor((p[1] - origin_[1]) / voxel_));
  const int z = static_cast<int>(std::floor((p[2] - origin_[2]) / voxel_));
  if (x < 0 || y < 0 || z < 0 || x >= nx_ || y >= ny_ || z >= nz_) return false;
  return marked_[(static_cast<size_t>(z) * ny_ + y) * nx_ + x] != 0;
}

}  // namespace mfcd::vision
