#pragma once
// GpiodLightRing: the eight LEDs on GPIO lines through libgpiod 1.6. The chip is found by name
// ("gpiochip0") or label ("mfc-leds"); the eight lines are requested as one bulk output request at
// configure() and held for the object's lifetime. Lines are driven all-off on release and on every
// error path.
#include <array>
#include <string>

#include "mfcd/hal/light_ring.hpp"

struct gpiod_chip;
struct gpiod_line_bulk;

namespace mfcd::hal {

struct GpiodLightRingConfig {
  std::string chip = "mfc-leds";                                    // name, label, path or number
  std::array<unsigned, kLedCount> offsets{0, 1, 2, 3, 4, 5, 6, 7};  // LED i → line offset
  bool active_low = false;                                          // LED lit when the line is driven low
  std::string consumer = "mfcd";
};

class GpiodLightRing final : public LightRing {
 public:
  explicit GpiodLightRing(GpiodLightRingConfig config);
  ~GpiodLightRing() override;
  GpiodLightRing(const GpiodLightRing&) = delete;
  GpiodLightRing& operator=(const GpiodLightRing&) = delete;

  void configure() override;
  void activate() override;
  void deactivate() override;
  void set(LedMask mask) override;
  LedMask state() const override { return mask_; }
  std::string describe() const override;

  const std::string& chip_name() const { return chip_name_; }    // "gpiochip3"
  const std::string& chip_label() const { return chip_label_; }  // "mfc-leds"

 private:
  void release() noexcept;
  bool all_off() noexcept;
  GpiodLightRingConfig config_;
  gpiod_chip* chip_ = nullptr;
  gpiod_line_bulk* bulk_ = nullptr;  // owned (heap: struct gpiod_line_bulk is large)
  std::string chip_name_, chip_label_;
  bool active_ = false;
  LedMask mask_ = 0;
};

}  // namespace mfcd::hal
