#include "mfcd/hal/error.hpp"

namespace mfcd::hal {

const char* to_string(ErrorCode code) noexcept {
  switch (code) {
    case ErrorCode::DeviceMissing:
      return "device missing";
    case ErrorCode::DeviceGone:
      return "device gone";
    case ErrorCode::WrongLine:
      return "wrong line";
    case ErrorCode::LineBusy:
      return "line busy";
    case ErrorCode::UnsupportedFormat:
      return "unsupported format";
    case ErrorCode::StreamTimeout:
      return "stream timeout";
    case ErrorCode::StaleFrames:
      return "stale frames";
    case ErrorCode::InvalidState:
      return "invalid state";
    case ErrorCode::MissingFeature:
      return "missing feature";
    case ErrorCode::Io:
      return "I/O error";
  }
  return "unknown";
}

}  // namespace mfcd::hal
