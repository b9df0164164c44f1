#pragma once
// The texels of an LED's shadow map that a render can read.
//
// A pixel of the rendered window looks up its LED's shadow map where its surface point
// (moved along the normal against acne) projects. When every visible surface lies within a
// known depth range, those points lie in the window's view frustum cut to that range, so the
// lookups fall inside the frustum's image in the map. Filling only that rectangle leaves every
// texel the render reads exactly as a whole-map fill would, at a fraction of the cost for a
// window much smaller than the frame (the maps always span the full frame's frustum).

#include "vision/camera/camera.hpp"

#include <opencv2/core.hpp>

namespace mfcd::vision {

struct ShadowFootprintQuery {
  cv::Matx44d unit_from_camera;  // camera frame (mm) -> map coordinates: [0,1]^2 across the map after division by w
  int map_size = 0;              // texels per side
  double z_near_mm = 0;          // camera-frame depth range of every surface the window shows
  double z_far_mm = 0;
  cv::Vec3d led_mm;          // the LED, camera frame
  double offset_per_mm = 0;  // a lookup moves off its surface by this times its distance to the LED
};

// The rectangle in map texels (x to the right, y as the map's t coordinate) that holds the
// lookups of every pixel of `camera`, grown by the 2x2 filter footprint and clipped to the
// map. The whole map when the range is empty or reaches behind the LED.
cv::Rect shadow_footprint(const ShadowFootprintQuery& query, const PinholeCamera& camera);

}  // namespace mfcd::vision
