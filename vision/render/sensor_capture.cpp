#include "vision/render/sensor_capture.hpp"

#include <algorithm>
#include <cmath>

namespace mfcd::vision {

void capture_frames(const SensorNoise& noise, uint64_t seed, MfcRender& out, cv::Mat1f& scratch) {
  const cv::Size size = out.ambient_linear.size();
  cv::RNG rng(seed);
  const auto read_var = static_cast<float>(noise.read_sigma_dn * noise.read_sigma_dn);
  const auto shot = static_cast<float>(noise.shot_dn_per_electron);
  auto capture = [&](const cv::Mat1f& signal, cv::Mat1b& image) {
    image.create(size);
    if (!noise.enabled) {
      signal.convertTo(image, CV_8U);  // rounds and saturates
      return;
    }
    scratch.create(size);
    // The same draws as one fill of the whole image (the generator runs through the pixels in
    // order either way), in pieces of at most 256 values: cv::RNG::fill keeps a piece that small
    // on the stack, and allocates a buffer for anything larger on every call.
    constexpr int kPiece = 256;
    for (int y = 0; y < size.height; ++y)
      for (int x = 0; x < size.width; x += kPiece) {
        cv::Mat1f piece = scratch(cv::Rect(x, y, std::min(kPiece, size.width - x), 1));
        rng.fill(piece, cv::RNG::NORMAL, 0.0, 1.0);
      }
    for (int y = 0; y < size.height; ++y) {
      const float* sg = signal.ptr<float>(y);
      const float* nz = scratch.ptr<float>(y);
      uint8_t* dst = image.ptr<uint8_t>(y);
      for (int x = 0; x < size.width; ++x) {
        const float v = sg[x] + std::sqrt(read_var + shot * std::max(sg[x], 0.f)) * nz[x];
        dst[x] = static_cast<uint8_t>(std::clamp(std::nearbyint(v), 0.f, 255.f));
      }
    }
  };
  out.frames.flash.resize(out.flash_linear.size());
  for (size_t i = 0; i < out.flash_linear.size(); ++i) capture(out.flash_linear[i], out.frames.flash[i]);
  capture(out.ambient_linear, out.frames.ambient);
}

}  // namespace mfcd::vision
