#pragma once
// The simulated cell with faults injected below the HAL's interfaces (SimulatedCamera's and
// SimulatedLightRing's hooks), on a schedule drawn from a seed: before a capture, with the given
// chance, one of a camera timeout, driver error buffers, a stale frame, an unplugged camera that
// comes back, or an LED line that fails to switch. Everything else is the real frame source and
// the real sequencer, so the daemon's handling of each fault is what is tested.
#include <cstdint>
#include <memory>
#include <random>

#include "daemon/frame_source.hpp"

namespace mfcd::daemon::test {

class FaultySource final : public FrameSource {
 public:
  // `percent`: chance of a fault before each capture, 0..100.
  FaultySource(std::unique_ptr<FrameSource> inner, std::uint64_t seed, int percent)
      : inner_(std::move(inner)), rng_(seed), percent_(percent) {}
  void activate() override { inner_->activate(); }
  void deactivate() noexcept override { inner_->deactivate(); }
  const hal::FrameSet& capture() override {
    if (SimulatedWorld* sim = inner_->simulation(); sim && std::uniform_int_distribution<int>(0, 99)(rng_) < percent_) {
      switch (std::uniform_int_distribution<int>(0, 4)(rng_)) {
        case 0:
          sim->simulated_camera().inject_timeouts(1);
          break;
        case 1:
          sim->simulated_camera().inject_error_frames(2);
          break;
        case 2:
          sim->simulated_camera().inject_stale_frames(1);
          break;
        case 3:
          sim->simulated_camera().inject_disconnect();
          break;
        default:
          sim->simulated_lights().fail_next_sets(1);
          break;
      }
    }
    return inner_->capture();
  }
  hal::ImageFormat format() const override { return inner_->format(); }
  hal::LedMask leds() const override { return inner_->leds(); }
  std::string describe() const override {
    return inner_->describe() + " with faults before " + std::to_string(percent_) + " % of the captures";
  }
  SimulatedWorld* simulation() noexcept override { return inner_->simulation(); }

 private:
  std::unique_ptr<FrameSource> inner_;
  std::mt19937_64 rng_;
  int percent_;
};

}  // namespace mfcd::daemon::test
