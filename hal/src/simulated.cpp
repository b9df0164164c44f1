#include "mfcd/hal/simulated.hpp"

#include <algorithm>
#include <cmath>
#include <thread>

#include "mfcd/hal/clock.hpp"
#include "mfcd/hal/error.hpp"

namespace mfcd::hal {

namespace {
constexpr std::uint8_t kTagMagic = 0xA5;

void put_pixel(Image& img, int x, int y, std::uint8_t value) {
  if (img.format().bits_per_pixel == 16) {
    auto* row = reinterpret_cast<std::uint16_t*>(img.row(y));
    row[x] = static_cast<std::uint16_t>(value << 8 | value);
  } else {
    img.row(y)[x] = value;
  }
}

std::uint8_t get_pixel(const Image& img, int x, int y) {
  if (img.format().bits_per_pixel == 16)
    return static_cast<std::uint8_t>(reinterpret_cast<const std::uint16_t*>(img.row(y))[x] >> 8);
  return img.row(y)[x];
}
}  // namespace

// ---------------------------------------------------------------------------------------------
void PatternSceneRenderer::render(LedMask lit, std::uint64_t exposure_index, Image& out) {
  const ImageFormat& f = out.format();
  // Unit vectors towards each lit LED; a pixel's brightness grows along their sum.
  double dx = 0, dy = 0;
  for (int i = 0; i < kLedCount; ++i) {
    if (lit & (1u << i)) {
      dx += std::cos(i * M_PI / 4);
      dy += std::sin(i * M_PI / 4);
    }
  }
  const double base = lit ? 110.0 : 40.0;  // ambient frames are dark
  const double sx = f.width > 1 ? 2.0 / (f.width - 1) : 0, sy = f.height > 1 ? 2.0 / (f.height - 1) : 0;
  for (int y = 0; y < f.height; ++y) {
    const double v = y * sy - 1.0;
    for (int x = 0; x < f.width; ++x) {
      const double u = x * sx - 1.0;
      const double value = std::clamp(base + 60.0 * (u * dx + v * dy), 0.0, 255.0);
      put_pixel(out, x, y, static_cast<std::uint8_t>(value));
    }
  }
  // Tag in the first row: magic, mask, 8 bytes of exposure index (little endian).
  if (f.width >= kTagPixels && f.height >= 1) {
    put_pixel(out, 0, 0, kTagMagic);
    put_pixel(out, 1, 0, lit);
    for (int b = 0; b < 8; ++b) put_pixel(out, 2 + b, 0, static_cast<std::uint8_t>(exposure_index >> (8 * b)));
  }
}

std::optional<PatternSceneRenderer::Tag> PatternSceneRenderer::decode(const Image& image) {
  if (image.format().width < kTagPixels || image.format().height < 1) return std::nullopt;
  if (get_pixel(image, 0, 0) != kTagMagic) return std::nullopt;
  Tag tag{get_pixel(image, 1, 0), 0};
  for (int b = 0; b < 8; ++b) tag.exposure_index |= std::uint64_t{get_pixel(image, 2 + b, 0)} << (8 * b);
  return tag;
}

// ---------------------------------------------------------------------------------------------
void SimulatedLightRing::configure() {
  if (configure_busy_)
    throw HalError(ErrorCode::LineBusy, describe() +
                                            ": line 0 is busy (held by consumer \"injected\"); "
                                            "check which process holds the lines");
  configured_ = true;
  drive(0);
}

void SimulatedLightRing::activate() {
  if (!configured_) throw HalError(ErrorCode::InvalidState, describe() + ": activate() before configure()");
  active_ = true;
}

void SimulatedLightRing::deactivate() {
  if (configured_) drive(0);
  active_ = false;
}

void SimulatedLightRing::set(LedMask mask) {
  if (!active_) throw HalError(ErrorCode::InvalidState, describe() + ": set() while not active");
  if (fail_sets_ > 0) {
    --fail_sets_;
    drive(0);  // like the real backend: all-off before reporting
    throw HalError(ErrorCode::Io, describe() + ": injected failure driving the lines");
  }
  drive(mask);
}

void SimulatedLightRing::drive(LedMask mask) {
  const std::int64_t now = monotonic_now_ns();
  if (mask != mask_) {
    previous_ = mask_;
    mask_ = mask;
    changed_ns_ = now;
  }
  if (history_.size() < history_.capacity()) history_.push_back({now, mask});
}

// ---------------------------------------------------------------------------------------------
SimulatedCamera::SimulatedCamera(SimulatedCameraConfig config, const LedStateSource& lights, SceneRenderer* renderer)
    : config_(std::move(config)), lights_(lights), renderer_(renderer ? renderer : &pattern_) {}

void SimulatedCamera::configure() {
  const ImageFormat& f = config_.format;
  if (f.width <= 0 || f.height <= 0 || (f.bits_per_pixel != 8 && f.bits_per_pixel != 16))
    throw HalError(ErrorCode::UnsupportedFormat, describe() + ": unsupported format " + std::to_string(f.width) + "x" +
                                                     std::to_string(f.height) + " " + std::to_string(f.bits_per_pixel) +
                                                     "-bit; check the configured size and depth (8 or 16)");
  configured_ = true;
}

void SimulatedCamera::activate() {
  if (!configured_) throw HalError(ErrorCode::InvalidState, describe() + ": activate() before configure()");
  active_ = true;
}

void SimulatedCamera::deactivate() { active_ = false; }

void SimulatedCamera::read(Image& out, FrameInfo& info) {
  if (!active_) throw HalError(ErrorCode::InvalidState, describe() + ": read() while not streaming");
  if (out.format() != config_.format)
    throw HalError(ErrorCode::InvalidState, describe() + ": read() into an image of the wrong format");
  if (reconnect_pending_) {  // the "device" came back: reopen, like V4L2Camera's reconnect
    reconnect_pending_ = false;
    ++stats_.reconnects;
  }
  if (disconnected_) {
    disconnected_ = false;
    reconnect_pending_ = true;
    throw HalError(ErrorCode::DeviceGone, describe() + ": device disconnected (injected); check the cable");
  }
  if (timeouts_ > 0) {
    --timeouts_;
    ++stats_.timeouts;
    throw HalError(ErrorCode::StreamTimeout, describe() + ": no frame within the watchdog (injected)");
  }
  while (error_frames_ > 0) {  // error buffers are re-queued and skipped; they still consume a sequence number
    --error_frames_;
    ++stats_.error_buffers;
    ++sequence_;
  }
  if (dropped_ > 0) {
    sequence_ += static_cast<std::uint32_t>(dropped_);
    stats_.dropped_frames += static_cast<std::uint64_t>(dropped_);
    dropped_ = 0;
  }

  LedMask lit;
  std::int64_t stamp;
  if (stale_ > 0) {
    // A frame already in the queue: exposed under the previous LED state, before the last change.
    --stale_;
    lit = lights_.previous_mask();
    stamp = lights_.last_change_ns() - 1;
  } else {
    lit = lights_.lit_mask();  // the LEDs lit at exposure start
    const std::int64_t start = monotonic_now_ns();
    if (config_.exposure_ns > 0) std::this_thread::sleep_for(std::chrono::nanoseconds(config_.exposure_ns));
    stamp = start + config_.exposure_ns;  // end-of-frame timestamp
  }
  renderer_->render(lit, exposures_++, out);
  info.timestamp_ns = stamp;
  info.sequence = sequence_++;
  ++stats_.frames;
}

}  // namespace mfcd::hal
