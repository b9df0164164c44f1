#pragma once
// MfcSequencer: one multi-flash capture (paper Section 4.2) — for each of the 8 LEDs: on, capture one
// exposure, off; then one ambient frame with all LEDs off. Every frame's exposure must lie inside its
// LED's on-window (ambient: after the last LED went off); frames exposed earlier are stale and are
// discarded, a bounded number of times per slot. The result is one FrameSet, preallocated at
// configure(), refilled by every read() without allocating.
#include <array>
#include <cstdint>

#include "mfcd/hal/camera.hpp"
#include "mfcd/hal/image.hpp"
#include "mfcd/hal/light_ring.hpp"

namespace mfcd::hal {

inline constexpr int kAmbientLed = -1;

struct SlotFrame {
  Image image;
  FrameInfo info;
  int led = kAmbientLed;    // 0..7, or kAmbientLed
  std::int64_t on_ns = 0;   // LED switched on (ambient: all LEDs confirmed off)
  std::int64_t off_ns = 0;  // LED switched off (ambient: frame accepted)
  int stale_discarded = 0;  // frames thrown away for this slot
};

struct FrameSet {
  static constexpr int kSlots = kLedCount + 1;  // 8 flash + 1 ambient (last)
  std::array<SlotFrame, kSlots> frames;
  std::uint64_t sequence = 0;  // 1 for the first FrameSet after configure()
};

struct SequencerConfig {
  int max_stale_frames_per_slot = 4;  // a slot fails after this many stale frames in a row
  std::int64_t settle_ns = 0;         // LED rise/fall time: exposure must start this long after a switch
};

struct SequencerStats {
  std::uint64_t frame_sets = 0;
  std::uint64_t stale_discarded = 0;
  std::uint64_t failures = 0;
};

class MfcSequencer {
 public:
  // Camera and ring are borrowed; the sequencer drives their lifecycle.
  MfcSequencer(Camera& camera, LightRing& lights, SequencerConfig config = {});
  ~MfcSequencer();
  MfcSequencer(const MfcSequencer&) = delete;
  MfcSequencer& operator=(const MfcSequencer&) = delete;

  void configure();  // configures camera and ring, allocates the FrameSet
  void activate();
  void deactivate();  // all LEDs off, streaming stopped
  // Captures one FrameSet. On any error the LEDs are switched off before the HalError propagates;
  // the sequencer stays active and the next read() starts a fresh set.
  const FrameSet& read();
  const SequencerStats& stats() const { return stats_; }

 private:
  void capture_slot(SlotFrame& slot, std::int64_t window_start_ns);
  Camera& camera_;
  LightRing& lights_;
  SequencerConfig config_;
  FrameSet set_;
  SequencerStats stats_;
  bool configured_ = false, active_ = false;
};

}  // namespace mfcd::hal
