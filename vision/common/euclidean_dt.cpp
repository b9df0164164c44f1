#include "vision/common/euclidean_dt.hpp"

#include <vector>

namespace mfcd::vision {

void squaredEuclideanDistance(const cv::Mat1b& sites, cv::Mat1i& d2, cv::Mat1i* nearest) {
  const int w = sites.cols, h = sites.rows;
  d2.create(h, w);
  if (nearest) nearest->create(h, w);
  // Column pass: vertical distance (and the nearest row) to a site in the same column.
  cv::Mat1i g(h, w), gy(h, w);
  const int inf = 1 << 20;
  for (int x = 0; x < w; ++x) {
    int last = -inf;
    for (int y = 0; y < h; ++y) {
      if (sites(y, x)) last = y;
      g(y, x) = last == -inf ? inf : y - last;
      gy(y, x) = last;
    }
    last = inf;
    for (int y = h - 1; y >= 0; --y) {
      if (sites(y, x)) last = y;
      if (last != inf && last - y < g(y, x)) {
        g(y, x) = last - y;
        gy(y, x) = last;
      }
    }
  }
  // Row pass: lower envelope of parabolas f(x') + (x - x')^2 with f = g^2.
  std::vector<int> v(w);
  std::vector<double> z(w + 1);
  for (int y = 0; y < h; ++y) {
    const int* gr = g.ptr<int>(y);
    int* out = d2.ptr<int>(y);
    int k = -1;
    for (int x = 0; x < w; ++x) {
      if (gr[x] >= inf) continue;
      const double fx = static_cast<double>(gr[x]) * gr[x] + static_cast<double>(x) * x;
      double s = 0;
      while (k >= 0) {
        const int p = v[k];
        const double fp = static_cast<double>(gr[p]) * gr[p] + static_cast<double>(p) * p;
        s = (fx - fp) / (2.0 * (x - p));
        if (s <= z[k])
          --k;
        else
          break;
      }
      ++k;
      v[k] = x;
      z[k] = k == 0 ? -1e300 : s;
      z[k + 1] = 1e300;
    }
    if (k < 0) {
      for (int x = 0; x < w; ++x) {
        out[x] = kInfiniteDistance2;
        if (nearest) (*nearest)(y, x) = kNoSite;
      }
      continue;
    }
    int j = 0;
    for (int x = 0; x < w; ++x) {
      while (z[j + 1] < x) ++j;
      const int p = v[j];
      const int dx = x - p;
      out[x] = dx * dx + gr[p] * gr[p];
      if (nearest) (*nearest)(y, x) = gy(y, p) * w + p;
    }
  }
}

}  // namespace mfcd::vision
