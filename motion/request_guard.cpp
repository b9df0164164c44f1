#include "motion/request_guard.hpp"

namespace mfcd::motion {

namespace {

std::uint16_t be16(const std::uint8_t* p) noexcept { return static_cast<std::uint16_t>((p[0] << 8) | p[1]); }

bool range_inside(std::uint32_t address, std::uint32_t count, std::uint32_t begin, std::uint32_t end) noexcept {
  return address >= begin && address + count <= end;
}

GuardVerdict refuse(std::uint8_t function, ModbusException why) noexcept {
  GuardVerdict v;
  v.function = function;
  v.exception = why;
  return v;
}

bool writable(const RegisterPolicy& policy, std::uint16_t address, std::uint16_t count) noexcept {
  return range_inside(address, count, policy.writable_begin, policy.writable_end) ||
         (policy.second_writable_end > policy.second_writable_begin &&
          range_inside(address, count, policy.second_writable_begin, policy.second_writable_end));
}

}  // namespace

std::size_t mbap_frame_size(std::span<const std::uint8_t, kMbapHeaderSize> header) noexcept {
  const std::uint16_t protocol = be16(&header[2]);
  const std::uint16_t length = be16(&header[4]);  // unit id + PDU
  if (protocol != 0 || length < 2 || length > kMaxAduSize - 6) return 0;
  return 6 + static_cast<std::size_t>(length);
}

GuardVerdict check_request(std::span<const std::uint8_t> adu, const RegisterPolicy& policy) noexcept {
  // The caller framed adu by its MBAP length, so at least the function code is present.
  if (adu.size() < kMbapHeaderSize + 1) return refuse(0, ModbusException::IllegalDataValue);
  const std::uint8_t function = adu[kMbapHeaderSize];
  const std::uint8_t* pdu = adu.data() + kMbapHeaderSize;
  const std::size_t pdu_size = adu.size() - kMbapHeaderSize;

  // The spec's order of checks: function code (0x01), then quantity and framing (0x03),
  // then address range (0x02).
  switch (function) {
    case 0x03:
    case 0x04: {
      if (pdu_size != 5) return refuse(function, ModbusException::IllegalDataValue);
      const std::uint16_t address = be16(pdu + 1);
      const std::uint16_t count = be16(pdu + 3);
      if (count < 1 || count > kMaxReadRegisters) return refuse(function, ModbusException::IllegalDataValue);
      if (!range_inside(address, count, 0, policy.readable_end))
        return refuse(function, ModbusException::IllegalDataAddress);
      return refuse(function, ModbusException::None);
    }
    case 0x06: {
      if (pdu_size != 5) return refuse(function, ModbusException::IllegalDataValue);
      const std::uint16_t address = be16(pdu + 1);
      if (!writable(policy, address, 1)) return refuse(function, ModbusException::IllegalDataAddress);
      GuardVerdict v = refuse(function, ModbusException::None);
      v.write = {address, 1, pdu + 3};
      return v;
    }
    case 0x10: {
      if (pdu_size < 6) return refuse(function, ModbusException::IllegalDataValue);
      const std::uint16_t address = be16(pdu + 1);
      const std::uint16_t count = be16(pdu + 3);
      const std::uint8_t byte_count = pdu[5];
      if (count < 1 || count > kMaxWriteRegisters || byte_count != 2 * count || pdu_size != 6u + byte_count)
        return refuse(function, ModbusException::IllegalDataValue);
      if (!writable(policy, address, count)) return refuse(function, ModbusException::IllegalDataAddress);
      GuardVerdict v = refuse(function, ModbusException::None);
      v.write = {address, count, pdu + 6};
      return v;
    }
    case 0x17: {
      if (pdu_size < 10) return refuse(function, ModbusException::IllegalDataValue);
      const std::uint16_t read_address = be16(pdu + 1);
      const std::uint16_t read_count = be16(pdu + 3);
      const std::uint16_t write_address = be16(pdu + 5);
      const std::uint16_t write_count = be16(pdu + 7);
      const std::uint8_t byte_count = pdu[9];
      if (read_count < 1 || read_count > kMaxReadRegisters || write_count < 1 || write_count > kMaxRwWriteRegisters ||
          byte_count != 2 * write_count || pdu_size != 10u + byte_count)
        return refuse(function, ModbusException::IllegalDataValue);
      if (!range_inside(read_address, read_count, 0, policy.readable_end) ||
          !writable(policy, write_address, write_count))
        return refuse(function, ModbusException::IllegalDataAddress);
      GuardVerdict v = refuse(function, ModbusException::None);
      v.write = {write_address, write_count, pdu + 10};
      return v;
    }
    default:
      // Coils, discrete inputs, diagnostics, file records, device id...: the map has none.
      return refuse(function, ModbusException::IllegalFunction);
  }
}

}  // namespace mfcd::motion
