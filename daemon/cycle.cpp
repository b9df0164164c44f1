// What cycle.hpp declares: the origin names, a slot's preallocated images and the copies into them.
#include "daemon/cycle.hpp"

#include <cstring>
#include <stdexcept>

namespace mfcd::daemon {

const char* to_string(CycleOrigin o) {
  switch (o) {
    case CycleOrigin::Plc:
      return "plc";
    case CycleOrigin::Control:
      return "control";
    case CycleOrigin::Continuous:
      return "continuous";
    case CycleOrigin::Benchmark:
      return "benchmark";
  }
  return "?";
}

void FrameSlot::allocate(const hal::ImageFormat& format) {
  mfc.flash.assign(hal::kLedCount, cv::Mat1b());
  for (int k = 0; k < hal::FrameSet::kSlots; ++k) {
    hal::Image& img = frames.frames[static_cast<std::size_t>(k)].image;
    img.allocate(format);
    cv::Mat1b view(format.height, format.width, img.data(), format.stride_bytes());
    if (k < hal::kLedCount)
      mfc.flash[static_cast<std::size_t>(k)] = view;
    else
      mfc.ambient = view;
  }
}

namespace {
void copy_frame_info(const hal::SlotFrame& a, hal::SlotFrame& b) {
  b.info = a.info;
  b.led = a.led;
  b.on_ns = a.on_ns;
  b.off_ns = a.off_ns;
  b.stale_discarded = a.stale_discarded;
}
}  // namespace

void copy_frame_set(const hal::FrameSet& from, hal::FrameSet& to) {
  for (std::size_t k = 0; k < from.frames.size(); ++k) {
    const hal::SlotFrame& a = from.frames[k];
    hal::SlotFrame& b = to.frames[k];
    if (a.image.size_bytes() != b.image.size_bytes())
      throw std::logic_error("copyFrameSet: FrameSet format differs from the preallocated slot");
    std::memcpy(b.image.data(), a.image.data(), a.image.size_bytes());
    copy_frame_info(a, b);
  }
  to.sequence = from.sequence;
}

void copy_frame_set(const hal::FrameSet& from, hal::FrameSet& to, const vision::FrameUndistorter& undistorter) {
  if (!undistorter.active()) {
    copy_frame_set(from, to);
    return;
  }
  for (std::size_t k = 0; k < from.frames.size(); ++k) {
    const hal::Image& a = from.frames[k].image;
    hal::Image& b = to.frames[k].image;
    if (a.size_bytes() != b.size_bytes() || a.format() != b.format())
      throw std::logic_error("copyFrameSet: FrameSet format differs from the preallocated slot");
    const hal::ImageFormat& f = a.format();
    const int type = f.bits_per_pixel == 16 ? CV_16UC1 : CV_8UC1;
    // Headers over the HAL's buffers (no allocation): the undistorter writes straight into the slot.
    const cv::Mat src(f.height, f.width, type, const_cast<std::uint8_t*>(a.data()), f.stride_bytes());
    cv::Mat dst(f.height, f.width, type, b.data(), f.stride_bytes());
    undistorter.apply(src, dst);
    if (dst.data != b.data()) throw std::logic_error("copyFrameSet: the undistorted image left the preallocated slot");
    copy_frame_info(from.frames[k], to.frames[k]);
  }
  to.sequence = from.sequence;
}

}  // namespace mfcd::daemon
