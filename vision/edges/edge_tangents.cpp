#include "vision/edges/edge_tangents.hpp"

#include "vision/edges/depth_edges.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace mfcd::vision {

float edge_tangent_at(const cv::Mat1b& mask, int x, int y, int radius) {
  // Integer sums (offsets are small integers): exact, and cheaper than double accumulation.
  int sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
  int n = 0;
  for (int v = std::max(0, y - radius); v <= std::min(mask.rows - 1, y + radius); ++v) {
    const uint8_t* m = mask.ptr<uint8_t>(v);
    for (int u = std::max(0, x - radius); u <= std::min(mask.cols - 1, x + radius); ++u)
      if (m[u]) {
        const int dx = u - x, dy = v - y;
        sx += dx;
        sy += dy;
        sxx += dx * dx;
        syy += dy * dy;
        sxy += dx * dy;
        ++n;
      }
  }
  if (n == 0) return 0.f;
  // The same double arithmetic as on double sums (the sums are exact either way).
  const double dn = n;
  const double mx = sx / dn, my = sy / dn;
  const double cxx = sxx / dn - mx * mx, cyy = syy / dn - my * my, cxy = sxy / dn - mx * my;
  double a = 0.5 * std::atan2(2 * cxy, cxx - cyy);
  if (a < 0) a += CV_PI;
  if (a >= CV_PI) a -= CV_PI;
  return static_cast<float>(a);
}

void edge_tangents(const cv::Mat1b& edges, cv::Mat1f& direction, int radius, const cv::Mat1f* shadow) {
  if (shadow && shadow->size() != edges.size())
    throw std::invalid_argument("edge tangents: the shadow map does not match the edge map");
  direction.create(edges.size());
  // Pixels are independent: rows are shared among the cores (once per cycle on the frame path).
#pragma omp parallel for schedule(static)
  for (int y = 0; y < edges.rows; ++y) {
    const uint8_t* e = edges.ptr<uint8_t>(y);
    float* d = direction.ptr<float>(y);
    const float* sh = shadow ? shadow->ptr<float>(y) : nullptr;
    for (int x = 0; x < edges.cols; ++x) {
      if (!e[x]) {
        d[x] = 0.f;
        continue;
      }
      const float t = edge_tangent_at(edges, x, y, radius);
      d[x] = sh ? oriented_tangent(t, sh[x]) : t;
    }
  }
}

}  // namespace mfcd::vision
