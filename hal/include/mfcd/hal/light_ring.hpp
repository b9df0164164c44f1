#pragma once
// LightRing: the eight flash LEDs around the lens. Backends: GpiodLightRing (gpiod_light_ring.hpp)
// and SimulatedLightRing (simulated.hpp). Lifecycle configure → activate → deactivate; the frame path
// only calls set().
#include <cstdint>
#include <string>

namespace mfcd::hal {

inline constexpr int kLedCount = 8;
using LedMask = std::uint8_t;  // bit i = LED i lit

class LightRing {
 public:
  virtual ~LightRing() = default;
  virtual void configure() = 0;   // acquire the lines (held until destruction), all off
  virtual void activate() = 0;    // set() allowed from now on
  virtual void deactivate() = 0;  // all off; set() refused until activate()
  // Drives exactly `mask`. On failure the backend has tried all-off before throwing HalError.
  virtual void set(LedMask mask) = 0;
  virtual LedMask state() const = 0;  // what was last driven successfully
  virtual std::string describe() const = 0;
};

}  // namespace mfcd::hal
