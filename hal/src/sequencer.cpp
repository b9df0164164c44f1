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
  if (config_.maxStaleFramesPerSlot < 0)
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

// Reads frames until one was exposed entirely after `windowStartNs` (plus the settle time) or the
// stale budget is spent. Frames exposed earlier are still in the queue from before the switch.
void MfcSequencer::captureSlot(SlotFrame& slot, std::int64_t windowStartNs) {
  slot.staleDiscarded = 0;
  const std::int64_t lead = camera_.exposureLeadNs();
  for (;;) {
    camera_.read(slot.image, slot.info);
    const std::int64_t exposureStart = slot.info.timestampNs - lead;
    if (exposureStart >= windowStartNs + config_.settleNs) return;
    ++slot.staleDiscarded;
    ++stats_.staleDiscarded;
    if (slot.staleDiscarded > config_.maxStaleFramesPerSlot) {
      const std::string what =
          slot.led == kAmbientLed ? std::string("ambient frame") : "LED " + std::to_string(slot.led);
      throw HalError(ErrorCode::StaleFrames,
                     "MFC sequencer: " + camera_.describe() + ": " + std::to_string(slot.staleDiscarded) +
                         " frames in a row for the " + what + " were exposed before its window opened (last frame " +
                         std::to_string((windowStartNs - exposureStart) / 1000) +
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
      slot.onNs = monotonicNowNs();
      captureSlot(slot, slot.onNs);
      lights_.set(0);
      slot.offNs = monotonicNowNs();
    }
    SlotFrame& ambient = set_.frames[kLedCount];
    ambient.onNs = set_.frames[kLedCount - 1].offNs;
    captureSlot(ambient, ambient.onNs);
    ambient.offNs = monotonicNowNs();
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
  ++stats_.frameSets;
  return set_;
}

}  // namespace mfcd::hal
