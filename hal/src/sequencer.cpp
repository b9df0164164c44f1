#include "mfcd/hal/sequencer.hpp"

#include <syslog.h>

#include <string>

#include "mfcd/hal/clock.hpp"
#include "mfcd/hal/error.hpp"

namespace mfcd::hal {

MfcSequencer::MfcSequencer(Camera& camera, LightRing& lights, SequencerConfig config)
    : camera_(camera), lights_(lights), config_(config) {}

MfcSequencer::~MfcSequencer() {
  if (active_) {
    try {
      deactivate();
    } catch (const HalError& e) {
      syslog(LOG_ERR, "mfcd hal: deactivating the sequencer on destruction: %s", e.what());
    }
  }
}

void MfcSequencer::configure() {
  if (active_) throw HalError(ErrorCode::InvalidState, "MFC sequencer: configure() while active; deactivate() first");
  if (config_.max_stale_frames_per_slot < 0)
    throw HalError(ErrorCode::InvalidState, "MFC sequencer: maxStaleFramesPerSlot must be >= 0");
  lights_.configure();
  camera_.configure();
  const ImageFormat format = camera_.format();
  for (int slot = 0; slot < FrameSet::kSlots; ++slot) {
    SlotFrame& frame = set_.frames[static_cast<std::size_t>(slot)];
    frame.image.allocate(format);  // the only allocation: every read() refills these buffers
    frame.led = slot < kLedCount ? slot : kAmbientLed;
  }
  set_.sequence = 0;
  configured_ = true;
}

void MfcSequencer::activate() {
  if (!configured_) throw HalError(ErrorCode::InvalidState, "MFC sequencer: activate() before configure()");
  lights_.activate();
  try {
    camera_.activate();
  } catch (...) {
    lights_.deactivate();
    throw;
  }
  active_ = true;
}

void MfcSequencer::deactivate() {
  if (!active_) return;
  active_ = false;
  // LEDs first: an LED must never stay lit because the camera failed to stop.
  lights_.deactivate();
  camera_.deactivate();
}

// Reads frames until one was exposed entirely after `window_start_ns` (plus the settle time) or the
// stale budget is spent. Frames exposed earlier are still in the queue from before the switch.
void MfcSequencer::capture_slot(SlotFrame& slot, std::int64_t window_start_ns) {
  slot.stale_discarded = 0;
  const std::int64_t lead = camera_.exposure_lead_ns();
  for (;;) {
    camera_.read(slot.image, slot.info);
    const std::int64_t exposure_start = slot.info.timestamp_ns - lead;
    if (exposure_start >= window_start_ns + config_.settle_ns) return;
    ++slot.stale_discarded;
    ++stats_.stale_discarded;
    if (slot.stale_discarded > config_.max_stale_frames_per_slot) {
      const std::string what =
          slot.led == kAmbientLed ? std::string("ambient frame") : "LED " + std::to_string(slot.led);
      throw HalError(ErrorCode::StaleFrames,
                     "MFC sequencer: " + camera_.describe() + ": " + std::to_string(slot.stale_discarded) +
                         " frames in a row for the " + what + " were exposed before its window opened (last frame " +
                         std::to_string((window_start_ns - exposure_start) / 1000) +
                         " us early); check the camera's buffer count, frame rate and timestamp source");
    }
  }
}

const FrameSet& MfcSequencer::read() {
  if (!active_) throw HalError(ErrorCode::InvalidState, "MFC sequencer: read() while not active; call activate()");
  try {
    for (int led = 0; led < kLedCount; ++led) {
      SlotFrame& slot = set_.frames[static_cast<std::size_t>(led)];
      lights_.set(static_cast<LedMask>(1u << led));
      slot.on_ns = monotonic_now_ns();
      capture_slot(slot, slot.on_ns);
      lights_.set(0);
      slot.off_ns = monotonic_now_ns();
    }
    SlotFrame& ambient = set_.frames[kLedCount];
    ambient.on_ns = set_.frames[kLedCount - 1].off_ns;
    capture_slot(ambient, ambient.on_ns);
    ambient.off_ns = monotonic_now_ns();
  } catch (...) {
    ++stats_.failures;
    try {
      lights_.set(0);
    } catch (const HalError& e) {
      syslog(LOG_ERR, "mfcd hal: switching LEDs off after a failed capture: %s", e.what());
    }
    throw;
  }
  ++set_.sequence;
  ++stats_.frame_sets;
  return set_;
}

}  // namespace mfcd::hal
