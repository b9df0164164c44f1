#pragma once
// Digital lines of one orientation channel (paper Sec. 3.5).
//
// The integral distance transform sums costs along lines of a channel's direction. For the sum of
// any segment to be a difference of two tensor entries, every pixel must lie on exactly one
// digital line, and a pixel's predecessor on its line must not depend on where the segment
// started. So all lines of a channel are integer translates of one pattern: for an x-major channel
// with slope m = tan(phi) the pattern is minor(k) = floor(k*m + 1/2) over the major coordinate k,
// and the line through pixel (x, y) is {(k, y - minor(x) + minor(k))}. y-major channels swap roles.
//
// A segment that starts at pixel s and spans L major steps covers the L+1 pixels
// (s.major + k, s.minor + minor(s.major + k) - minor(s.major)), k = 0..L. Its pixels depend slightly
// on s.major (the pattern is anchored at major = 0): compared with a pure translate of the segment,
// each pixel moves by at most one pixel along the minor axis. The spatial bound of the search
// accounts for exactly that (search/bounds.hpp).
#include <cstdint>
#include <vector>

#include "vision/common/orientation.hpp"

namespace mfcd::vision {

class DigitalLineTable {
 public:
  DigitalLineTable() = default;
  // Tables cover major coordinates 0 .. extent-1 (callers add their own guard offsets).
  DigitalLineTable(const OrientationChannels& channels, int width, int height);

  bool xMajor(int channel) const { return xMajor_[channel] != 0; }
  // minor(k) of the channel's pattern, k in [0, extent of the major axis).
  const int16_t* minor(int channel) const { return minor_[channel].data(); }
  int q() const { return static_cast<int>(minor_.size()); }

 private:
  std::vector<std::vector<int16_t>> minor_;
  std::vector<uint8_t> xMajor_;
};

// Longest segment span whose IDT3 sum is exact in 16 bits: 256 pixels x 255 units < 2^16.
inline constexpr int kMaxSegmentSpan = 255;

// One segment in digital form: start pixel, channel, major-axis span L (L+1 pixels).
// The start is the end with the smaller major coordinate, so pixels run in +major direction.
struct DigitalSegment {
  int16_t x = 0, y = 0;  // start pixel, relative to a template origin or absolute
  uint8_t channel = 0;
  uint8_t span = 0;  // L: the segment has L+1 pixels
  int pixels() const { return span + 1; }
};

// Visits the pixels of a digital segment placed at absolute start (sx, sy); the minor pattern is
// indexed by major coordinate + `patternOrigin` (the tensor's guard/margin offset).
template <class F>
inline void forEachPixel(const DigitalLineTable& table, int channel, int sx, int sy, int span, int patternOrigin,
                         F&& f) {
  const int16_t* m = table.minor(channel);
  if (table.xMajor(channel)) {
    const int base = m[sx + patternOrigin];
    for (int k = 0; k <= span; ++k) f(sx + k, sy + m[sx + k + patternOrigin] - base);
  } else {
    const int base = m[sy + patternOrigin];
    for (int k = 0; k <= span; ++k) f(sx + m[sy + k + patternOrigin] - base, sy + k);
  }
}

}  // namespace mfcd::vision
