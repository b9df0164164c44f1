#include "vision/templates/render_window.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace mfcd::vision {

namespace {
constexpr double kMarginPx = 8;
}

double widest_shadow_px(const CameraConfig& config, double near_mm, double far_mm) {
  const PinholeCamera& cam = config.camera;
  const double f = std::max(cam.fx(), cam.fy());
  double baseline = 0;
  for (const auto& p : config.flashes.positions_mm) baseline = std::max(baseline, std::hypot(p[0], p[1]));
  return baseline * f * (far_mm - near_mm) / (near_mm * far_mm);
}

int window_half_px(const CameraConfig& config, double object_px, double near_mm, double far_mm) {
  return static_cast<int>(std::ceil(object_px + widest_shadow_px(config, near_mm, far_mm) + kMarginPx));
}

cv::Rect window_on_axis(const PinholeCamera& cam, int half) {
  const cv::Point c(static_cast<int>(std::lround(cam.cx())), static_cast<int>(std::lround(cam.cy())));
  return cv::Rect(c.x - half, c.y - half, 2 * half + 1, 2 * half + 1) & cv::Rect(cv::Point(0, 0), cam.image_size);
}

cv::Rect part_region(const CameraConfig& config, const PinholeCamera& camera, const Mesh& mesh, const cv::Matx33d& R,
                     const cv::Vec3d& t, double far_mm) {
  const cv::Rect whole(cv::Point(0, 0), camera.image_size);
  double x0 = std::numeric_limits<double>::max(), y0 = x0, x1 = -x0, y1 = -x0, near = x0;
  for (const auto& v : mesh.vertices) {
    const cv::Vec3d p = R * cv::Vec3d(v[0], v[1], v[2]) + t;
    if (p[2] <= 0) return whole;  // reaches behind the lens: no bound from the projection
    const cv::Point2d q(camera.fx() * p[0] / p[2] + camera.cx(), camera.fy() * p[1] / p[2] + camera.cy());
    x0 = std::min(x0, q.x), x1 = std::max(x1, q.x), y0 = std::min(y0, q.y), y1 = std::max(y1, q.y);
    near = std::min(near, p[2]);
  }
  if (mesh.vertices.empty()) return {};
  const double grow = (near < far_mm ? widest_shadow_px(config, near, far_mm) : 0) + kMarginPx;
  const cv::Point lo(static_cast<int>(std::floor(x0 - grow)), static_cast<int>(std::floor(y0 - grow)));
  const cv::Point hi(static_cast<int>(std::ceil(x1 + grow)), static_cast<int>(std::ceil(y1 + grow)));
  return cv::Rect(lo, hi + cv::Point(1, 1)) & whole;
}

}  // namespace mfcd::vision
