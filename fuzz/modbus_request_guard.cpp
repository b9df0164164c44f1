// motion/request_guard.hpp on a Modbus/TCP byte stream, framed as motion/modbus_server.cpp frames
// it: an MBAP header, mbap_frame_size(), then check_request() on the whole frame, with the
// server's register policy. Besides the sanitizers, the harness checks what the server relies
// on when a request is let through: the frame fits its 260-byte buffer, and a write lies inside
// the frame and inside one writable range.

#include "fuzz/fuzz_support.hpp"
#include "motion/register_map.hpp"
#include "motion/request_guard.hpp"

#include <cstring>
#include <memory>

namespace {

using namespace mfcd::motion;

// motion/modbus_requests.cpp's kPolicy: reads [0, 96) (the whole map), writes [0, 6) (control
// block) or [36, 50) (robot pose block).
constexpr RegisterPolicy kPolicy{reg::kBlockSize, 0, reg::kWritableEnd, reg::kRobotPoseBegin, reg::kRobotPoseEnd};

bool inside(uint32_t address, uint32_t count, uint32_t begin, uint32_t end) {
  return address >= begin && address + count <= end;
}

void check_verdict(const uint8_t* adu, size_t size, const GuardVerdict& v) {
  using mfcd::fuzz::finding;
  if (v.function != adu[kMbapHeaderSize]) finding("verdict names another function code than the frame's");
  const RegisterWrite& w = v.write;
  if (v.exception != ModbusException::None) {
    if (w.count != 0) finding("a refused request carries a write");
    return;
  }
  const uint8_t* pdu = adu + kMbapHeaderSize;
  switch (v.function) {
    case 0x03:
    case 0x04: {
      const uint16_t address = static_cast<uint16_t>(pdu[1] << 8 | pdu[2]);
      const uint16_t count = static_cast<uint16_t>(pdu[3] << 8 | pdu[4]);
      if (count == 0 || !inside(address, count, 0, kPolicy.readable_end)) finding("read outside the readable block");
      if (w.count != 0) finding("a read carries a write");
      return;
    }
    case 0x06:
    case 0x10:
    case 0x17:
      break;
    default:
      finding("an unsupported function was let through");
  }
  if (w.count == 0) finding("an accepted write request writes nothing");
  if (!inside(w.address, w.count, kPolicy.writable_begin, kPolicy.writable_end) &&
      !inside(w.address, w.count, kPolicy.second_writable_begin, kPolicy.second_writable_end))
    finding("write outside the writable ranges");
  if (w.values < pdu + 1 || w.values + 2 * static_cast<size_t>(w.count) > adu + size)
    finding("write values lie outside the frame");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  size_t pos = 0;
  while (size - pos >= kMbapHeaderSize) {
    const size_t frame = mbap_frame_size(std::span<const uint8_t, kMbapHeaderSize>(data + pos, kMbapHeaderSize));
    if (frame == 0) break;  // the server closes the connection: no trustworthy frame boundary
    if (frame < kMbapHeaderSize + 1 || frame > kMaxAduSize) mfcd::fuzz::finding("frame size outside 8..260");
    if (size - pos < frame) break;  // the server waits for the rest (until its frame timeout)
    // A heap copy of exactly the frame, so a read past it is an AddressSanitizer report.
    const std::unique_ptr<uint8_t[]> adu(new uint8_t[frame]);
    std::memcpy(adu.get(), data + pos, frame);
    check_verdict(adu.get(), frame, check_request(std::span<const uint8_t>(adu.get(), frame), kPolicy));
    pos += frame;
  }
  return 0;
}
