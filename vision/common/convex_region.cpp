#include "vision/common/convex_region.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

namespace mfcd::vision {

namespace {

// > 0 when o -> a -> b turns counter-clockwise in a y-up frame (clockwise on screen); exact.
int64_t cross(cv::Point o, cv::Point a, cv::Point b) {
  return int64_t(a.x - o.x) * (b.y - o.y) - int64_t(a.y - o.y) * (b.x - o.x);
}

}  // namespace

void ConvexRegion::build(std::span<const cv::Point> points) {
  hull_.clear();
  top_ = 0;
  bottom_ = -1;
  if (points.empty()) return;
  // Only the leftmost and rightmost point of each row can be a hull vertex (any other lies
  // between two of its row), so when the points fill their rows densely (a placed template: ~1000
  // points over ~100 rows) the sort gets those two per row instead of all of them. The hull, its
  // first vertex (the leftmost, lowest-y point, which is its row's leftmost) and its order are the
  // same either way.
  int ylo = points[0].y, yhi = points[0].y;
  for (const auto& p : points) ylo = std::min(ylo, p.y), yhi = std::max(yhi, p.y);
  const size_t span = static_cast<size_t>(int64_t(yhi) - ylo + 1);
  if (span <= points.size() / 2) {
    row_left_.assign(span, std::numeric_limits<int>::max());
    row_right_.assign(span, std::numeric_limits<int>::min());
    for (const auto& p : points) {
      const size_t r = static_cast<size_t>(p.y - ylo);
      row_left_[r] = std::min(row_left_[r], p.x);
      row_right_[r] = std::max(row_right_[r], p.x);
    }
    sorted_.clear();
    for (size_t r = 0; r < span; ++r) {
      if (row_left_[r] > row_right_[r]) continue;  // no point in this row
      const int y = ylo + static_cast<int>(r);
      sorted_.emplace_back(row_left_[r], y);
      if (row_right_[r] != row_left_[r]) sorted_.emplace_back(row_right_[r], y);
    }
  } else {
    sorted_.assign(points.begin(), points.end());
  }
  std::sort(sorted_.begin(), sorted_.end(),
            [](cv::Point a, cv::Point b) { return a.x != b.x ? a.x < b.x : a.y < b.y; });
  sorted_.erase(std::unique(sorted_.begin(), sorted_.end()), sorted_.end());
  // Lower chain left to right, then upper chain right to left; a vertex that does not turn the
  // same way (collinear or a repeat) is dropped.
  const size_t n = sorted_.size();
  hull_.resize(2 * n);
  size_t k = 0;
  for (size_t i = 0; i < n; ++i) {
    while (k >= 2 && cross(hull_[k - 2], hull_[k - 1], sorted_[i]) <= 0) --k;
    hull_[k++] = sorted_[i];
  }
  for (size_t i = n - 1, lower = k + 1; i-- > 0;) {
    while (k >= lower && cross(hull_[k - 2], hull_[k - 1], sorted_[i]) <= 0) --k;
    hull_[k++] = sorted_[i];
  }
  hull_.resize(k > 1 ? k - 1 : 1);  // the chain ends on its start (one point: just it)

  int ymin = hull_[0].y, ymax = hull_[0].y;
  for (const auto& p : hull_) ymin = std::min(ymin, p.y), ymax = std::max(ymax, p.y);
  top_ = ymin;
  bottom_ = ymax;
  const size_t rows = static_cast<size_t>(ymax - ymin + 1);
  low_.assign(rows, std::numeric_limits<double>::infinity());
  high_.assign(rows, -std::numeric_limits<double>::infinity());
  // The hull is convex, so within a row's band its x extent is reached on its boundary.
  if (hull_.size() == 1) cover_edge(hull_[0], hull_[0]);
  for (size_t i = 0; i < hull_.size(); ++i) cover_edge(hull_[i], hull_[(i + 1) % hull_.size()]);
  first_.resize(rows);
  last_.resize(rows);
  for (size_t r = 0; r < rows; ++r) {
    // Column x's square [x-0.5, x+0.5] meets [low, high].
    first_[r] = static_cast<int>(std::ceil(low_[r] - 0.5));
    last_[r] = static_cast<int>(std::floor(high_[r] + 0.5));
  }
}

void ConvexRegion::reserve(size_t points, int rows) {
  sorted_.reserve(points);
  hull_.reserve(2 * points);
  const size_t r = static_cast<size_t>(std::max(rows, 0));
  low_.reserve(r);
  high_.reserve(r);
  first_.reserve(r);
  last_.reserve(r);
  row_left_.reserve(r);
  row_right_.reserve(r);
}

void ConvexRegion::cover_edge(cv::Point a, cv::Point b) {
  if (a.y > b.y) std::swap(a, b);
  // The vertices are integers, so the bands of rows a.y..b.y are the ones the edge meets.
  const double dy = b.y - a.y;
  auto x_at = [&](double y) { return a.x + (b.x - a.x) * ((y - a.y) / dy); };
  for (int y = a.y; y <= b.y; ++y) {
    // The part of the edge within the band [y-0.5, y+0.5]; a level edge lies wholly in its row.
    const double y0 = std::max(y - 0.5, double(a.y)), y1 = std::min(y + 0.5, double(b.y));
    const double x0 = dy == 0 ? a.x : x_at(y0), x1 = dy == 0 ? b.x : x_at(y1);
    const size_t r = static_cast<size_t>(y - top_);
    low_[r] = std::min({low_[r], x0, x1});
    high_[r] = std::max({high_[r], x0, x1});
  }
}

}  // namespace mfcd::vision
