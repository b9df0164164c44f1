#pragma once
// Simulated backends (PipeWire-style: same interfaces as the hardware ones). The simulated camera
// renders whichever LEDs the simulated ring has lit *at exposure time* — that is the lockstep the
// sequencer relies on. Both backends take injected faults so error paths are testable without hardware.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "mfcd/hal/camera.hpp"
#include "mfcd/hal/light_ring.hpp"

namespace mfcd::hal {

// What the simulated camera needs to know about the lights: the current state and, for frames
// exposed before the last change (stale frames), the state before it.
class LedStateSource {
 public:
  virtual ~LedStateSource() = default;
  virtual LedMask lit_mask() const = 0;
  virtual LedMask previous_mask() const = 0;
  virtual std::int64_t last_change_ns() const = 0;
};

// Produces the image the camera would see with `lit` LEDs on. The CAD-based cell renderer
// (vision/render) implements this too; the HAL ships only the deterministic pattern below.
class SceneRenderer {
 public:
  virtual ~SceneRenderer() = default;
  virtual void render(LedMask lit, std::uint64_t exposure_index, Image& out) = 0;
};

// Deterministic test scene: the first row carries a tag (magic, lit mask, exposure index) and the
// rest is a ramp brightening towards the lit LEDs' directions (LED i sits at i*45 degrees), so an
// image is recognisable by eye and by decode().
class PatternSceneRenderer final : public SceneRenderer {
 public:
  struct Tag {
    LedMask lit;
    std::uint64_t exposure_index;
  };
  void render(LedMask lit, std::uint64_t exposure_index, Image& out) override;
  static std::optional<Tag> decode(const Image& image);
  static constexpr int kTagPixels = 10;  // images must be at least this wide
};

class SimulatedLightRing final : public LightRing, public LedStateSource {
 public:
  explicit SimulatedLightRing(std::string name = "sim-leds") : name_(std::move(name)) {}
  void configure() override;
  void activate() override;
  void deactivate() override;
  void set(LedMask mask) override;
  LedMask state() const override { return mask_; }
  std::string describe() const override { return "simulated light ring " + name_; }

  LedMask lit_mask() const override { return mask_; }
  LedMask previous_mask() const override { return previous_; }
  std::int64_t last_change_ns() const override { return changed_ns_; }

  // Fault injection, below the interface.
  void fail_next_sets(int count) { fail_sets_ = count; }           // set() fails (after forcing all-off)
  void fail_configure_busy(bool busy) { configure_busy_ = busy; }  // configure() reports a busy line

  // Every set() with its time, kept in preallocated storage (no allocation on the frame path).
  struct Event {
    std::int64_t time_ns;
    LedMask mask;
  };
  void record_history(std::size_t capacity) {
    history_.clear();
    history_.reserve(capacity);
  }
  const std::vector<Event>& history() const { return history_; }

 private:
  void drive(LedMask mask);
  std::string name_;
  bool configured_ = false, active_ = false;
  LedMask mask_ = 0, previous_ = 0;
  std::int64_t changed_ns_ = 0;
  int fail_sets_ = 0;
  bool configure_busy_ = false;
  std::vector<Event> history_;
};

struct SimulatedCameraConfig {
  ImageFormat format{64, 48, 8};
  std::string name = "sim-camera";
  // Exposure time: read() "exposes" for this long (sleeps) and stamps the end of it, like a
  // camera with end-of-frame timestamps. 0 = instantaneous (benchmarks).
  std::int64_t exposure_ns = 0;
};

class SimulatedCamera final : public Camera {
 public:
  // `lights` and `renderer` are borrowed; nullptr renderer = the built-in PatternSceneRenderer.
  SimulatedCamera(SimulatedCameraConfig config, const LedStateSource& lights, SceneRenderer* renderer = nullptr);
  void configure() override;
  void activate() override;
  void deactivate() override;
  void read(Image& out, FrameInfo& info) override;
  ImageFormat format() const override { return config_.format; }
  std::int64_t exposure_lead_ns() const override { return config_.exposure_ns; }
  const CameraStats& stats() const override { return stats_; }
  std::string describe() const override { return "simulated camera " + config_.name; }

  // Fault injection, below the interface. Each applies to the next `count` frames.
  void inject_timeouts(int count) { timeouts_ = count; }          // read() throws StreamTimeout
  void inject_stale_frames(int count) { stale_ = count; }         // frame exposed before the last LED change
  void inject_error_frames(int count) { error_frames_ = count; }  // driver error buffers: skipped, counted
  void inject_dropped_frames(int count) { dropped_ = count; }     // sequence gap of `count` before next frame
  void inject_disconnect() { disconnected_ = true; }              // next read() throws DeviceGone, then reconnects

 private:
  SimulatedCameraConfig config_;
  const LedStateSource& lights_;
  PatternSceneRenderer pattern_;
  SceneRenderer* renderer_;
  bool configured_ = false, active_ = false;
  std::uint32_t sequence_ = 0;
  std::uint64_t exposures_ = 0;
  CameraStats stats_;
  int timeouts_ = 0, stale_ = 0, error_frames_ = 0, dropped_ = 0;
  bool disconnected_ = false, reconnect_pending_ = false;
};

}  // namespace mfcd::hal
