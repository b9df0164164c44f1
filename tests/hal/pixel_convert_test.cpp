// convert_to_grey (vectorisable loops) against an obviously-right per-pixel reference, random inputs.
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "mfcd/hal/v4l2_camera.hpp"

namespace mfcd::hal {
namespace {

// Reference: decode one pixel's luma as 16-bit, then map to the output depth.
std::uint16_t reference_luma16(SourceFormat f, const std::vector<std::uint8_t>& src, std::size_t stride, int x, int y) {
  const std::size_t row = static_cast<std::size_t>(y) * stride;
  switch (f) {
    case SourceFormat::Grey:
      return static_cast<std::uint16_t>(src[row + static_cast<std::size_t>(x)] * 257);
    case SourceFormat::Y16:
      return static_cast<std::uint16_t>(src[row + 2 * static_cast<std::size_t>(x)] +
                                        256 * src[row + 2 * static_cast<std::size_t>(x) + 1]);
    case SourceFormat::Yuyv: {
      // Macropixel Y0 U Y1 V: pixel x is Y0 if even, Y1 if odd.
      const std::size_t macro = row + 4 * static_cast<std::size_t>(x / 2);
      return static_cast<std::uint16_t>(src[macro + (x % 2 == 0 ? 0 : 2)] * 257);
    }
  }
  return 0;
}

std::uint32_t read_pixel(const Image& img, int x, int y) {
  if (img.format().bits_per_pixel == 8) return img.row(y)[x];
  return reinterpret_cast<const std::uint16_t*>(img.row(y))[x];
}

TEST(PixelConvert, MatchesReferenceOnRandomFrames) {
  std::mt19937 rng(1234);
  for (SourceFormat f : {SourceFormat::Grey, SourceFormat::Y16, SourceFormat::Yuyv}) {
    for (int depth : {8, 16}) {
      for (int trial = 0; trial < 20; ++trial) {
        const int w = 2 * std::uniform_int_distribution<int>(1, 40)(rng);  // YUYV needs even widths
        const int h = std::uniform_int_distribution<int>(1, 17)(rng);
        const std::size_t bpp = f == SourceFormat::Grey ? 1 : 2;
        const std::size_t stride =
            bpp * static_cast<std::size_t>(w) + static_cast<std::size_t>(trial % 3) * 8;  // padded rows too
        std::vector<std::uint8_t> src(stride * static_cast<std::size_t>(h));
        for (auto& b : src) b = static_cast<std::uint8_t>(rng());
        Image out(ImageFormat{w, h, depth});
        convert_to_grey(f, src.data(), stride, out);
        for (int y = 0; y < h; ++y)
          for (int x = 0; x < w; ++x) {
            const std::uint16_t ref16 = reference_luma16(f, src, stride, x, y);
            const std::uint32_t expected = depth == 16 ? ref16 : static_cast<std::uint32_t>(ref16 >> 8);
            ASSERT_EQ(read_pixel(out, x, y), expected) << "format " << static_cast<int>(f) << " depth " << depth
                                                       << " at " << x << "," << y << " size " << w << "x" << h;
          }
      }
    }
  }
}

}  // namespace
}  // namespace mfcd::hal
