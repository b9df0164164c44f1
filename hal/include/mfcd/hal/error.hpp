#pragma once
// Errors raised by the hardware-abstraction layer. Every message names the device (node, chip, line)
// and says what to check, because the operator reading the journal has no debugger.
#include <stdexcept>
#include <string>

namespace mfcd::hal {

enum class ErrorCode {
  DeviceMissing,      // /dev/videoN, the GPIO chip or the GenICam camera does not exist
  DeviceGone,         // the device disappeared while in use (ENODEV: unplugged; GenICam: stopped answering)
  WrongLine,          // GPIO line offset outside the chip; a camera line that is missing or not an output
  LineBusy,           // GPIO line held by another consumer (EBUSY)
  UnsupportedFormat,  // no usable pixel format / frame size
  StreamTimeout,      // no frame within the dequeue watchdog / frame timeout
  StaleFrames,        // sequencer: no frame inside the LED's on-window after the retries
  InvalidState,       // lifecycle misuse (read() before activate(), ...)
  MissingFeature,     // the camera lacks a GenICam feature the configuration needs (LineSelector, ...)
  Io,                 // any other system-call failure
};

const char* to_string(ErrorCode code) noexcept;

class HalError : public std::runtime_error {
 public:
  HalError(ErrorCode code, const std::string& message) : std::runtime_error(message), code_(code) {}
  ErrorCode code() const noexcept { return code_; }

 private:
  ErrorCode code_;
};

}  // namespace mfcd::hal
