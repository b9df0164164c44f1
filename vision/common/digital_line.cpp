#include "vision/common/digital_line.hpp"

#include <algorithm>
#include <cmath>

namespace mfcd::vision {

DigitalLineTable::DigitalLineTable(const OrientationChannels& channels, int width, int height) {
  const int q = channels.q();
  minor_.resize(q);
  xMajor_.resize(q);
  for (int c = 0; c < q; ++c) {
    const bool xm = channels.xMajor(c);
    xMajor_[c] = xm ? 1 : 0;
    const double slope = channels.minorSlope(c);
    const int extent = (xm ? width : height) + 1;
    auto& table = minor_[c];
    table.resize(extent);
    for (int k = 0; k < extent; ++k) table[k] = static_cast<int16_t>(std::floor(k * slope + 0.5));
  }
}

}  // namespace mfcd::vision
