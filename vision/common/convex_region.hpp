#pragma once
// The convex hull of a set of image points and the pixels it covers, through kept buffers: the
// converse check (explained_edge_fraction) runs once per hypothesis on the frame path, where
// cv::convexHull and cv::fillConvexPoly allocate on every call.
#include <span>
#include <vector>

#include <opencv2/core/types.hpp>

namespace mfcd::vision {

class ConvexRegion {
 public:
  // The hull of `points` (Andrew's monotone chain), its vertices in order around it without
  // repeated or collinear ones; and the pixels whose unit square meets it, row by row. No allocation once the buffers
  // have grown. Empty input gives an empty region.
  void build(std::span<const cv::Point> points);
  // Grows the buffers for up to `points` points spanning up to `rows` rows: build() then
  // allocates nothing for such sets, not even the first time.
  void reserve(size_t points, int rows);

  const std::vector<cv::Point>& hull() const { return hull_; }
  bool empty() const { return hull_.empty(); }
  // Rows top()..bottom() (inclusive) hold covered pixels; every row between does.
  int top() const { return top_; }
  int bottom() const { return bottom_; }
  // The covered columns of row y (top() <= y <= bottom()): first..last, inclusive. A pixel (x, y)
  // is covered when the square [x-0.5, x+0.5] x [y-0.5, y+0.5] meets the hull (boundary included):
  // the outline's own pixels are inside, as the part's outline edges should be.
  int first(int y) const { return first_[static_cast<size_t>(y - top_)]; }
  int last(int y) const { return last_[static_cast<size_t>(y - top_)]; }

 private:
  void cover_edge(cv::Point a, cv::Point b);

  std::vector<cv::Point> sorted_, hull_;
  std::vector<double> low_, high_;  // per row: x extent of the hull within the row's band
  std::vector<int> first_, last_;
  std::vector<int> row_left_, row_right_;  // build scratch: per row, the extreme x of the points
  int top_ = 0, bottom_ = -1;
};

}  // namespace mfcd::vision
