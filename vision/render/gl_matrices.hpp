#pragma once
// The renderer's matrices in OpenGL's conventions: camera frame (mm, OpenCV axes) to clip
// space for a pinhole, rigid transforms as 4x4, and the column-major floats GL takes.

#include <opencv2/core.hpp>

#include <array>

namespace mfcd::vision::gl_matrices {

// Column-major 4x4 for glUniformMatrix4fv.
using Mat4 = std::array<float, 16>;

inline Mat4 to_gl(const cv::Matx44d& m) {
  Mat4 out{};
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) out[static_cast<size_t>(c * 4 + r)] = static_cast<float>(m(r, c));
  return out;
}

// Camera frame -> clip space for a pinhole K, so that window pixel centres (x + 0.5, y + 0.5)
// coincide with OpenCV pixel (x, y). Window row y = OpenCV row v (no flip): glReadPixels'
// first row is image row 0. Depth is mapped to [near, far] in the usual OpenGL way.
inline cv::Matx44d clip_from_camera(const cv::Matx33d& K, cv::Size size, double n, double f) {
  const double W = size.width, H = size.height;
  return {2 * K(0, 0) / W,
          2 * K(0, 1) / W,
          2 * (K(0, 2) + 0.5) / W - 1,
          0,
          0,
          2 * K(1, 1) / H,
          2 * (K(1, 2) + 0.5) / H - 1,
          0,
          0,
          0,
          (f + n) / (f - n),
          -2 * f * n / (f - n),
          0,
          0,
          1,
          0};
}

inline cv::Matx44d model_matrix(const cv::Matx33d& R, const cv::Vec3d& t) {
  return {R(0, 0), R(0, 1), R(0, 2), t[0], R(1, 0), R(1, 1), R(1, 2), t[1],
          R(2, 0), R(2, 1), R(2, 2), t[2], 0,       0,       0,       1};
}

}  // namespace mfcd::vision::gl_matrices
