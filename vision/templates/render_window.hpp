#pragma once
// The part of the image a teaching render needs (the template views, the edge offset plate):
// rendering only it costs a fraction of the whole image.

#include "vision/camera/camera.hpp"

#include <algorithm>
#include <cmath>

namespace mfcd::vision {

// Half the side of a square window that holds an object of image radius `object_px`, the widest
// shadow any of the camera's flashes casts from depth `near_mm` onto a surface at `far_mm`
// (baseline * f * (far - near) / (near * far) for the farthest LED) and an 8 px margin.
inline int window_half_px(const CameraConfig& config, double object_px, double near_mm, double far_mm) {
  const PinholeCamera& cam = config.camera;
  const double f = std::max(cam.fx(), cam.fy());
  double baseline = 0;
  for (const auto& p : config.flashes.positions_mm) baseline = std::max(baseline, std::hypot(p[0], p[1]));
  const double shadow = baseline * f * (far_mm - near_mm) / (near_mm * far_mm);
  return static_cast<int>(std::ceil(object_px + shadow + 8));
}

// The window of that half side around the principal point, clipped to the image.
inline cv::Rect window_on_axis(const PinholeCamera& cam, int half) {
  const cv::Point c(static_cast<int>(std::lround(cam.cx())), static_cast<int>(std::lround(cam.cy())));
  return cv::Rect(c.x - half, c.y - half, 2 * half + 1, 2 * half + 1) & cv::Rect(cv::Point(0, 0), cam.image_size);
}

}  // namespace mfcd::vision
