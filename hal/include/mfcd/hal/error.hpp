#pragma once
// Errors raised by the hardware-abstraction layer. Every message names the device (node, chip, line)
// and says what to check, because the operator reading the journal has no debugger.
#include <stdexcept>
#include <string>

namespace mfcd::hal {

enum class ErrorCode {
  DeviceMissing,      // /dev/videoN or the GPIO chip does not exist
  DeviceGone,         // the device disappeared while in use (ENODEV: unplugged)
  WrongLine,          // GPIO line offset outside the chip
  LineBusy,           // GPIO line held by another consumer (EBUSY)
  UnsupportedFormat,  // no usable pixel format / frame size
  StreamTimeout,      // no frame within the dequeue watchdog
  StaleFrames,        // sequencer: no frame inside the LED's on-window after the retries
  InvalidState,       // lifecycle misuse (read() before activate(), ...)
  Io,                 // any other system-call failure
};

const char* toString(ErrorCode code) noexcept;

class HalError : public std::runtime_error {
public:
  HalError(ErrorCode code, const std::string& message) : std::runtime_error(message), code_(code) {}
  ErrorCode code() const noexcept { return code_; }

private:
  ErrorCode code_;
};

}  // namespace mfcd::hal
