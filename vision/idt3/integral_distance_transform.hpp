#pragma once
// IDT3, the integral distance transform tensor (paper Sec. 3.5, Eqs. 14-15): every entry holds the
// sum of DT3 along the digital line of its channel's direction (vision/common/digital_line.hpp)
// from the image border up to that pixel, so the cost of any segment of that channel is a
// difference of two entries: O(1) per segment, O(m) per template of m segments.
//
// Storage: 16-bit entries that wrap modulo 2^16. A difference of two entries is still exact as
// long as the true segment sum is below 2^16; per-pixel costs are at most 255 units, so any
// segment of at most 256 pixels is exact, and the search splits longer segments
// (search/oriented_template.hpp). Planes have a one-pixel zero guard on every side so that the
// entry "before" a segment starting on the border is a valid read. 640x480, q = 60: 37.2 MB.
#include <cstdint>
#include <vector>

#include "vision/common/digital_line.hpp"
#include "vision/dt3/directional_distance_transform.hpp"

namespace mfcd::vision {

class IntegralDistanceTransform {
 public:
  void compute(const DirectionalDistanceTransform& dt3);

  int width() const { return width_; }  // image size (without guard)
  int height() const { return height_; }
  int q() const { return q_; }
  int stride() const { return width_ + 2; }
  const DigitalLineTable& lines() const { return lines_; }
  const uint16_t* plane(int channel) const {
    return data_.data() + static_cast<size_t>(channel) * stride() * (height_ + 2);
  }
  size_t bytes() const { return data_.size() * sizeof(uint16_t); }

  // Plane offsets (relative to the plane start) of the entry at the segment's last pixel and of
  // the entry before its first pixel, for a segment starting at image pixel (sx, sy).
  struct Ends {
    int32_t end, before;
  };
  Ends ends(int channel, int sx, int sy, int span) const {
    const int16_t* m = lines_.minor(channel);
    const int X = sx + 1, Y = sy + 1, s = stride();
    if (lines_.xMajor(channel)) {
      const int Xe = X + span;
      return {(Y + m[Xe] - m[X]) * s + Xe, (Y - (m[X] - m[X - 1])) * s + X - 1};
    }
    const int Ye = Y + span;
    return {Ye * s + X + m[Ye] - m[Y], (Y - 1) * s + X - (m[Y] - m[Y - 1])};
  }
  // Sum of DT3 over the segment's pixels (units of 1/kCostScale px). The segment must lie
  // inside the image and have span <= kMaxSegmentSpan.
  uint32_t segmentCost(int channel, int sx, int sy, int span) const {
    const Ends e = ends(channel, sx, sy, span);
    const uint16_t* p = plane(channel);
    return static_cast<uint16_t>(p[e.end] - p[e.before]);
  }

 private:
  int width_ = 0, height_ = 0, q_ = 0;
  bool oriented_ = false;
  std::vector<uint16_t> data_;
  DigitalLineTable lines_;
  // x-major channels: per column X, whether the predecessor is on the neighbouring row (depends
  // only on the channel's pattern and the width: made on a resize).
  std::vector<std::vector<uint8_t>> hops_;
};

}  // namespace mfcd::vision
