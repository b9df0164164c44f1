#include "vision/edges/edge_tangents.hpp"

#include <algorithm>
#include <cmath>

namespace mfcd::vision {

float edge_tangent_at(const cv::Mat1b& mask, int x, int y, int radius) {
  double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
  int n = 0;
  for (int v = std::max(0, y - radius); v <= std::min(mask.rows - 1, y + radius); ++v) {
    const uint8_t* m = mask.ptr<uint8_t>(v);
    for (int u = std::max(0, x - radius); u <= std::min(mask.cols - 1, x + radius); ++u)
      if (m[u]) {
        const double dx = u - x, dy = v - y;
        sx += dx;
        sy += dy;
        sxx += dx * dx;
        syy += dy * dy;
        sxy += dx * dy;
        ++n;
      }
  }
  if (n == 0) return 0.f;
  const double mx = sx / n, my = sy / n;
  const double cxx = sxx / n - mx * mx, cyy = syy / n - my * my, cxy = sxy / n - mx * my;
  double a = 0.5 * std::atan2(2 * cxy, cxx - cyy);
  if (a < 0) a += CV_PI;
  if (a >= CV_PI) a -= CV_PI;
  return static_cast<float>(a);
}

void edge_tangents(const cv::Mat1b& edges, cv::Mat1f& direction, int radius) {
  direction.create(edges.size());
  for (int y = 0; y < edges.rows; ++y) {
    const uint8_t* e = edges.ptr<uint8_t>(y);
    float* d = direction.ptr<float>(y);
    for (int x = 0; x < edges.cols; ++x) d[x] = e[x] ? edge_tangent_at(edges, x, y, radius) : 0.f;
  }
}

}  // namespace mfcd::vision
