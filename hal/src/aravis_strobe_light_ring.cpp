#include "mfcd/hal/aravis_strobe_light_ring.hpp"

#include <syslog.h>

#include <bit>

#include "mfcd/hal/error.hpp"

namespace mfcd::hal {

AravisStrobeLightRing::~AravisStrobeLightRing() {
  try {
    deactivate();
  } catch (const HalError& e) {
    syslog(LOG_ERR, "mfcd hal: %s: selecting no LED on destruction: %s", describe().c_str(), e.what());
  }
}

std::string AravisStrobeLightRing::describe() const { return "strobe outputs of " + camera_.describe(); }

void AravisStrobeLightRing::configure() {
  if (!camera_.has_strobe())
    throw HalError(ErrorCode::InvalidState, describe() +
                                                ": the camera has no strobe configuration (lines); "
                                                "check the lights section of the configuration");
  configured_ = true;
}

void AravisStrobeLightRing::activate() {
  if (!configured_) throw HalError(ErrorCode::InvalidState, describe() + ": activate() before configure()");
  active_ = true;
}

void AravisStrobeLightRing::deactivate() {
  if (!active_) return;
  active_ = false;
  // No LED selected: even a stray exposure then flashes nothing.
  if (camera_.selected_led() != AravisCamera::kNoLed) camera_.select_led(AravisCamera::kNoLed);
  mask_ = 0;
}

void AravisStrobeLightRing::set(LedMask mask) {
  if (!active_) throw HalError(ErrorCode::InvalidState, describe() + ": set() while not active; call activate()");
  if (std::popcount(static_cast<unsigned>(mask)) > 1)
    throw HalError(ErrorCode::InvalidState, describe() + ": LED mask 0x" + std::to_string(mask) +
                                                " lights several LEDs; the select lines carry one LED index at a time");
  try {
    camera_.select_led(mask == 0 ? AravisCamera::kNoLed : std::countr_zero(static_cast<unsigned>(mask)));
    mask_ = mask;
  } catch (const HalError&) {
    // All off: a gone camera exposes nothing, otherwise try to deselect before reporting.
    try {
      camera_.select_led(AravisCamera::kNoLed);
      mask_ = 0;
    } catch (const HalError& e) {
      syslog(LOG_CRIT, "mfcd hal: %s: cannot deselect the LEDs: %s", describe().c_str(), e.what());
    }
    throw;
  }
}

}  // namespace mfcd::hal
