#include "vision/render/shadow_footprint.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace mfcd::vision {

cv::Rect shadow_footprint(const ShadowFootprintQuery& q, const PinholeCamera& camera) {
  const cv::Rect whole(0, 0, q.map_size, q.map_size);
  if (!(q.z_near_mm > 0) || !(q.z_far_mm >= q.z_near_mm) || !std::isfinite(q.z_far_mm) || !(q.offset_per_mm >= 0))
    return whole;
  // A lookup point is a surface point P = z * r (r a ray through the window, z in [near, far])
  // plus an offset e with |e_i| <= offset. With z' = z + e_z it is z' * r + (e_x - e_z r_x,
  // e_y - e_z r_y, 0): a point of the frustum cut to [near - offset, far + offset] moved across
  // the optical axis by at most offset * (1 + max |r_x|, |r_y|). That set is the convex
  // hull of the cut frustum's 8 corners each moved to the 4 corners of that square, and a
  // perspective map (every point in front of the LED) keeps convex hulls: the box of those 32
  // projections holds every lookup.
  const double W = camera.image_size.width, H = camera.image_size.height;
  const cv::Matx33d K_inv = camera.K.inv();
  std::array<cv::Vec3d, 4> rays;
  double reach = 0;
  for (int k = 0; k < 4; ++k) {
    const double u = (k & 1) ? W - 0.5 : -0.5, v = (k & 2) ? H - 0.5 : -0.5;
    const cv::Vec3d r = K_inv * cv::Vec3d(u, v, 1.0);  // z = 1 (K's last row is 0 0 1)
    rays[static_cast<size_t>(k)] = r;
    reach = std::max({reach, std::abs(r[0]), std::abs(r[1])});
  }
  // The distance to the LED is at most |P| + |L|, and |P| <= z_far * |r| <= z_far * (1 + 2 reach).
  const double offset = q.offset_per_mm * (q.z_far_mm * (1 + 2 * reach) + cv::norm(q.led_mm));
  const double across = offset * (1 + reach);
  double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
  for (double z : {q.z_near_mm - offset, q.z_far_mm + offset})
    for (const cv::Vec3d& r : rays)
      for (int dx = -1; dx <= 1; dx += 2)
        for (int dy = -1; dy <= 1; dy += 2) {
          const cv::Vec4d p(z * r[0] + dx * across, z * r[1] + dy * across, z, 1.0);
          const cv::Vec4d s = q.unit_from_camera * p;
          if (!(s[3] > 1e-9)) return whole;  // at or behind the LED: the projection is unbounded
          const double x = s[0] / s[3] * q.map_size, y = s[1] / s[3] * q.map_size;
          x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
        }
  // Texel centres sit at half-integers; linear filtering reads the two texels around a point,
  // so one texel beyond the box on each side, plus one for rounding.
  const double lo_x = std::floor(x0) - 2, lo_y = std::floor(y0) - 2, hi_x = std::ceil(x1) + 2, hi_y = std::ceil(y1) + 2;
  if (!(lo_x < q.map_size && lo_y < q.map_size && hi_x > 0 && hi_y > 0)) return {};
  const auto clamp = [&](double t) { return static_cast<int>(std::clamp(t, 0.0, static_cast<double>(q.map_size))); };
  const cv::Rect box(cv::Point(clamp(lo_x), clamp(lo_y)), cv::Point(clamp(hi_x), clamp(hi_y)));
  return box & whole;
}

}  // namespace mfcd::vision
