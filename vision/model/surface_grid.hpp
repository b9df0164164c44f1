#pragma once
// Which points of space lie on (within a tolerance of) a mesh's surface, answered in O(1) from a
// voxel grid. Used to tell which edge points of a near-symmetric part are its asymmetric
// features: a point whose image under the part's would-be symmetry is not on the surface
// belongs to a feature that breaks it (the breaker's toggle turned by 180 degrees lands in air).

#include "vision/model/mesh.hpp"

#include <opencv2/core.hpp>

#include <cstdint>
#include <vector>

namespace mfcd::vision {

class SurfaceGrid {
 public:
  // Marks every voxel (edge `voxel_mm`) within `tolerance_mm` of a triangle. Throws
  // std::invalid_argument on an empty mesh or a non-positive voxel or tolerance.
  SurfaceGrid(const Mesh& mesh, double voxel_mm, double tolerance_mm);

  // Whether `p` (mm, the mesh's frame) lies within the tolerance of the surface, decided for the
  // centre of its voxel: true for every point within tolerance - sqrt(3)/2 voxel, false for every
  // point farther than tolerance + sqrt(3)/2 voxel.
  bool near(const cv::Vec3d& p) const;

  double voxel_mm() const { return voxel_; }
  double tolerance_mm() const { return tolerance_; }

 private:
  double voxel_ = 0, tolerance_ = 0;
  cv::Vec3d origin_;  // corner of voxel (0, 0, 0)
  int nx_ = 0, ny_ = 0, nz_ = 0;
  std::vector<uint8_t> marked_;  // x fastest
};

// The shortest distance from `p` to the mesh's surface, by visiting every triangle (the reference
// SurfaceGrid is tested against; slow).
double distance_to_surface(const Mesh& mesh, const cv::Vec3d& p);

}  // namespace mfcd::vision
