#pragma once
// AravisStrobeLightRing: the eight LEDs fired by a GenICam camera's digital outputs instead of GPIO
// lines (docs/hal.md, "Camera strobe"). It borrows the AravisCamera, which configures the lines
// (strobe + three select lines, CameraStrobeConfig) at its configure(); set(1 << i) selects LED i,
// which then lights during the camera's exposures only, set(0) selects none. One LED at a time:
// the select lines carry an index, not a mask.
#include <string>

#include "mfcd/hal/aravis_camera.hpp"
#include "mfcd/hal/light_ring.hpp"

namespace mfcd::hal {

class AravisStrobeLightRing final : public LightRing {
 public:
  explicit AravisStrobeLightRing(AravisCamera& camera) : camera_(camera) {}
  ~AravisStrobeLightRing() override;
  AravisStrobeLightRing(const AravisStrobeLightRing&) = delete;
  AravisStrobeLightRing& operator=(const AravisStrobeLightRing&) = delete;

  // Checks that the camera has a strobe configuration; the lines themselves are set up by the
  // camera's configure() (the sequencer configures the ring first).
  void configure() override;
  void activate() override;
  void deactivate() override;
  void set(LedMask mask) override;
  LedMask state() const override { return mask_; }
  std::string describe() const override;

 private:
  AravisCamera& camera_;
  bool configured_ = false, active_ = false;
  LedMask mask_ = 0;
};

}  // namespace mfcd::hal
