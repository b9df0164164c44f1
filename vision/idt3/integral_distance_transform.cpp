#include "vision/idt3/integral_distance_transform.hpp"

#include <algorithm>
#include <cstring>
#include <vector>

namespace mfcd::vision {

void IntegralDistanceTransform::compute(const DirectionalDistanceTransform& dt3) {
  const bool resized =
      width_ != dt3.width() || height_ != dt3.height() || q_ != dt3.q() || oriented_ != dt3.params().oriented;
  width_ = dt3.width();
  height_ = dt3.height();
  q_ = dt3.q();
  oriented_ = dt3.params().oriented;
  const int s = stride(), rows = height_ + 2;
  const size_t planeSize = static_cast<size_t>(s) * rows;
  if (resized) {
    data_.assign(planeSize * q_, 0);  // guards stay zero from here on
    lines_ = DigitalLineTable(dt3.channels(), s, rows);
    hops_.assign(static_cast<size_t>(q_), {});
    for (int c = 0; c < q_; ++c) {
      if (!lines_.xMajor(c)) continue;
      const int16_t* m = lines_.minor(c);
      hops_[c].assign(static_cast<size_t>(width_) + 1, 0);
      for (int X = 1; X <= width_; ++X) hops_[c][X] = m[X] != m[X - 1];
    }
  }

#pragma omp parallel for schedule(dynamic, 1)
  for (int c = 0; c < q_; ++c) {
    uint16_t* I = data_.data() + planeSize * c;
    const uint8_t* D = dt3.plane(c);
    const int16_t* m = lines_.minor(c);
    if (lines_.xMajor(c)) {
      // Predecessor of (X, Y) is (X-1, Y - (m[X] - m[X-1])): one step left, at most one row
      // up (rising lines) or down (falling lines). Sweep rows in the direction that makes the
      // predecessor row available, columns left to right.
      const bool rising = m[2] >= m[1] && m[s - 1] >= m[1];
      // Whether the predecessor is on the neighbouring row, per column (the same for all rows).
      const std::vector<uint8_t>& hop = hops_[c];
      for (int i = 0; i < height_; ++i) {
        const int Y = rising ? 1 + i : height_ - i;
        uint16_t* row = I + static_cast<size_t>(Y) * s;
        const uint16_t* other = rising ? row - s : row + s;  // the row a hop comes from
        const uint8_t* d = D + static_cast<size_t>(Y - 1) * width_;
        // The running sum stays in a register; only a hop reads the neighbouring row.
        uint16_t v = 0;
        for (int X = 1; X <= width_; ++X) {
          const uint16_t pred = hop[X] ? other[X - 1] : v;
          v = static_cast<uint16_t>(d[X - 1] + pred);
          row[X] = v;
        }
      }
    } else {
      // Predecessor of (X, Y) is (X - (m[Y] - m[Y-1]), Y-1): the whole previous row, shifted.
      for (int Y = 1; Y <= height_; ++Y) {
        const int dx = m[Y] - m[Y - 1];
        uint16_t* row = I + static_cast<size_t>(Y) * s;
        const uint16_t* prev = row - s - dx;
        const uint8_t* d = D + static_cast<size_t>(Y - 1) * width_;
        for (int X = 1; X <= width_; ++X) row[X] = static_cast<uint16_t>(d[X - 1] + prev[X]);
      }
    }
  }
}

}  // namespace mfcd::vision
