#include <cstring>

#include "mfcd/hal/v4l2_camera.hpp"

namespace mfcd::hal {

// 8 → 16 bit scales full range (v * 257: 255 → 65535); 16 → 8 bit keeps the high byte.
// The loops are written so GCC vectorises them; tests/hal compares them to a per-pixel reference.
void convert_to_grey(SourceFormat source, const std::uint8_t* src, std::size_t src_stride, Image& out) {
  const ImageFormat& f = out.format();
  const int w = f.width;
  for (int y = 0; y < f.height; ++y) {
    const std::uint8_t* s = src + static_cast<std::size_t>(y) * src_stride;
    if (f.bits_per_pixel == 8) {
      std::uint8_t* d = out.row(y);
      switch (source) {
        case SourceFormat::Grey:
          std::memcpy(d, s, static_cast<std::size_t>(w));
          break;
        case SourceFormat::Y16:
          for (int x = 0; x < w; ++x) d[x] = s[2 * x + 1];  // little-endian: high byte second
          break;
        case SourceFormat::Yuyv:
          for (int x = 0; x < w; ++x) d[x] = s[2 * x];  // Y0 U Y1 V: luma on even bytes
          break;
      }
    } else {
      auto* d = reinterpret_cast<std::uint16_t*>(out.row(y));
      switch (source) {
        case SourceFormat::Grey:
          for (int x = 0; x < w; ++x) d[x] = static_cast<std::uint16_t>(s[x] * 257u);
          break;
        case SourceFormat::Y16:
          for (int x = 0; x < w; ++x) d[x] = static_cast<std::uint16_t>(s[2 * x] | s[2 * x + 1] << 8);
          break;
        case SourceFormat::Yuyv:
          for (int x = 0; x < w; ++x) d[x] = static_cast<std::uint16_t>(s[2 * x] * 257u);
          break;
      }
    }
  }
}

}  // namespace mfcd::hal
