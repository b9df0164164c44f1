// Checks a Modbus/TCP request completely before libmodbus sees it.
//
// libmodbus 3.1.6's modbus_reply() trusts the request it is given: the MBAP length is not
// checked against the PDU, write byte counts are not always checked against the register
// quantity, and FC 0x17 (read/write multiple registers) had a heap overflow on inconsistent
// write ranges (CVE-2022-0367; CVE-2019-14462/14463 were short-frame reads in the same
// parser). mfcd frames the TCP stream itself and hands modbus_reply() only requests that
// this guard has found well formed, in range and of a function the map supports.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace mfcd::motion {

inline constexpr std::size_t kMbapHeaderSize = 7;           // transaction(2) protocol(2) length(2) unit(1)
inline constexpr std::size_t kMaxAduSize = 260;             // Modbus/TCP: 7 + 253-byte PDU
inline constexpr std::uint16_t kMaxReadRegisters = 125;     // FC 0x03/0x04, and the read half of 0x17
inline constexpr std::uint16_t kMaxWriteRegisters = 123;    // FC 0x10
inline constexpr std::uint16_t kMaxRwWriteRegisters = 121;  // write half of FC 0x17

enum class ModbusException : std::uint8_t {
  None = 0,
  IllegalFunction = 0x01,
  IllegalDataAddress = 0x02,
  IllegalDataValue = 0x03,
  ServerDeviceFailure = 0x04,
  ServerDeviceBusy = 0x06,
};

// Total ADU size announced by an MBAP header, or 0 when the header cannot start a valid
// frame (protocol id not 0, length field < 2 or > 254). After a bad header the byte stream
// has no trustworthy frame boundary, so the connection must be closed.
std::size_t mbap_frame_size(std::span<const std::uint8_t, kMbapHeaderSize> header) noexcept;

// Which register ranges requests may touch: [0, readable_end) for reads; for writes
// [writable_begin, writable_end) and, when not empty, [second_writable_begin,
// second_writable_end). One write must lie wholly inside one of the ranges.
struct RegisterPolicy {
  std::uint16_t readable_end;
  std::uint16_t writable_begin;
  std::uint16_t writable_end;
  std::uint16_t second_writable_begin = 0;
  std::uint16_t second_writable_end = 0;
};

// One write a request makes, for the server's command handling.
struct RegisterWrite {
  std::uint16_t address = 0;
  std::uint16_t count = 0;
  const std::uint8_t* values = nullptr;  // big-endian register values, 2 * count bytes inside the frame
};

struct GuardVerdict {
  ModbusException exception = ModbusException::None;  // None: forward to libmodbus
  std::uint8_t function = 0;
  RegisterWrite write;  // count 0 when the request writes nothing
};

// adu is one complete frame whose size mbap_frame_size() accepted.
GuardVerdict check_request(std::span<const std::uint8_t> adu, const RegisterPolicy& policy) noexcept;

}  // namespace mfcd::motion
