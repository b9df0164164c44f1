#include "mfcd/hal/gpiod_light_ring.hpp"

#include <gpiod.h>
#include <syslog.h>

#include <cerrno>
#include <cstring>
#include <memory>
#include <string>

#include "mfcd/hal/error.hpp"

namespace mfcd::hal {

GpiodLightRing::GpiodLightRing(GpiodLightRingConfig config) : config_(std::move(config)) {}

GpiodLightRing::~GpiodLightRing() { release(); }

std::string GpiodLightRing::describe() const {
  if (chip_) return "GPIO chip " + chip_name_ + " [" + chip_label_ + "]";
  return "GPIO chip '" + config_.chip + "'";
}

// Drives every LED off. Returns false if even that failed (the caller is already on an error path).
bool GpiodLightRing::all_off() noexcept {
  if (!bulk_) return true;
  int values[kLedCount] = {};
  if (gpiod_line_set_value_bulk(bulk_, values) < 0) {
    syslog(LOG_CRIT, "mfcd hal: %s: cannot switch the LEDs off: %s", describe().c_str(), std::strerror(errno));
    return false;
  }
  mask_ = 0;
  return true;
}

void GpiodLightRing::release() noexcept {
  if (bulk_) {
    all_off();
    gpiod_line_release_bulk(bulk_);
    delete bulk_;
    bulk_ = nullptr;
  }
  if (chip_) gpiod_chip_close(chip_);
  chip_ = nullptr;
  active_ = false;
}

void GpiodLightRing::configure() {
  if (bulk_) return;  // the request is held for the object's lifetime
  // Name ("gpiochip0"), path, label ("mfc-leds") or number.
  chip_ = gpiod_chip_open_lookup(config_.chip.c_str());
  if (!chip_) {
    const int err = errno;
    throw HalError(err == EACCES ? ErrorCode::Io : ErrorCode::DeviceMissing,
                   "GPIO chip '" + config_.chip + "': not found by name, path, label or number (" + std::strerror(err) +
                       "); check the chip with gpiodetect and that the daemon may open /dev/gpiochip*");
  }
  chip_name_ = gpiod_chip_name(chip_);
  chip_label_ = gpiod_chip_label(chip_);
  const unsigned num_lines = gpiod_chip_num_lines(chip_);
  for (int i = 0; i < kLedCount; ++i) {
    const unsigned offset = config_.offsets[static_cast<std::size_t>(i)];
    const auto wrong_line = [&](const std::string& why) {
      const std::string msg = describe() + ": LED " + std::to_string(i) + " line offset " + std::to_string(offset) +
                              " " + why + "; check the offsets in the configuration against gpioinfo " + chip_name_;
      release();
      throw HalError(ErrorCode::WrongLine, msg);
    };
    if (offset >= num_lines) wrong_line("is out of range: the chip has " + std::to_string(num_lines) + " lines");
    for (int j = 0; j < i; ++j)
      if (config_.offsets[static_cast<std::size_t>(j)] == offset)
        wrong_line("is also used by LED " + std::to_string(j));
  }

  auto bulk = std::make_unique<gpiod_line_bulk>();
  if (gpiod_chip_get_lines(chip_, config_.offsets.data(), kLedCount, bulk.get()) < 0) {
    const std::string msg =
        describe() + ": cannot get the LED lines: " + std::strerror(errno) + "; check the offsets with gpioinfo";
    release();
    throw HalError(ErrorCode::WrongLine, msg);
  }
  const int flags = config_.active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
  int off[kLedCount] = {};  // logical 0 = LED off, whatever the polarity
  if (gpiod_line_request_bulk_output_flags(bulk.get(), config_.consumer.c_str(), flags, off) < 0) {
    const int err = errno;
    std::string msg;
    if (err == EBUSY) {
      // Name the line and who holds it: the operator's next step is to stop that process.
      msg = describe() + ": LED lines busy:";
      for (int i = 0; i < kLedCount; ++i) {
        gpiod_line* line = bulk->lines[i];
        gpiod_line_update(line);
        if (gpiod_line_is_used(line)) {
          const char* who = gpiod_line_consumer(line);
          msg += " line " + std::to_string(gpiod_line_offset(line)) + " (LED " + std::to_string(i) +
                 ") held by consumer \"" + (who ? who : "?") + "\";";
        }
      }
      msg += " check gpioinfo " + chip_name_ + " and stop the other program (only one process may drive the LEDs)";
    } else {
      msg = describe() + ": requesting the LED lines as outputs: " + std::strerror(err) + "; check gpioinfo " +
            chip_name_;
    }
    release();
    throw HalError(err == EBUSY ? ErrorCode::LineBusy : ErrorCode::Io, msg);
  }
  bulk_ = bulk.release();
  mask_ = 0;
}

void GpiodLightRing::activate() {
  if (!bulk_) throw HalError(ErrorCode::InvalidState, describe() + ": activate() before configure()");
  active_ = true;
}

void GpiodLightRing::deactivate() {
  active_ = false;
  if (bulk_ && !all_off())
    throw HalError(ErrorCode::Io, describe() + ": switching the LEDs off failed: " + std::strerror(errno) +
                                      "; check the chip (dmesg) — LEDs may still be lit");
}

void GpiodLightRing::set(LedMask mask) {
  if (!active_) throw HalError(ErrorCode::InvalidState, describe() + ": set() while not active");
  int values[kLedCount];
  for (int i = 0; i < kLedCount; ++i) values[i] = (mask >> i) & 1;
  if (gpiod_line_set_value_bulk(bulk_, values) < 0) {
    const int err = errno;
    all_off();
    throw HalError(ErrorCode::Io,
                   describe() + ": driving the LED lines: " + std::strerror(err) + "; check the chip (dmesg)");
  }
  mask_ = mask;
}

}  // namespace mfcd::hal
