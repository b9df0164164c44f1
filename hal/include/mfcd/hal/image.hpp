#pragma once
// A grey image in a buffer the HAL owns. Allocated once (configure()), refilled in place on every
// read(): the frame path never allocates. 8-bit or 16-bit (host-endian uint16) pixels.
#include <cstddef>
#include <cstdint>
#include <vector>

namespace mfcd::hal {

struct ImageFormat {
  int width = 0;
  int height = 0;
  int bits_per_pixel = 8;  // 8 or 16
  bool operator==(const ImageFormat&) const = default;
  std::size_t bytes_per_pixel() const { return bits_per_pixel == 16 ? 2 : 1; }
  std::size_t stride_bytes() const { return static_cast<std::size_t>(width) * bytes_per_pixel(); }
  std::size_t size_bytes() const { return stride_bytes() * static_cast<std::size_t>(height); }
};

class Image {
 public:
  Image() = default;
  explicit Image(const ImageFormat& format) { allocate(format); }
  void allocate(const ImageFormat& format) {
    format_ = format;
    data_.assign(format.size_bytes(), 0);
  }
  const ImageFormat& format() const { return format_; }
  std::uint8_t* data() { return data_.data(); }
  const std::uint8_t* data() const { return data_.data(); }
  std::size_t size_bytes() const { return data_.size(); }
  std::uint8_t* row(int y) { return data_.data() + static_cast<std::size_t>(y) * format_.stride_bytes(); }
  const std::uint8_t* row(int y) const { return data_.data() + static_cast<std::size_t>(y) * format_.stride_bytes(); }

 private:
  ImageFormat format_;
  std::vector<std::uint8_t> data_;
};

}  // namespace mfcd::hal
