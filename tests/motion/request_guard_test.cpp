#include "motion/request_guard.hpp"

#include <gtest/gtest.h>

#include <vector>

using namespace mfcd::motion;

namespace {

constexpr RegisterPolicy kPolicy{64, 0, 4};

// MBAP header with a length field consistent with the PDU.
std::vector<std::uint8_t> adu(std::vector<std::uint8_t> pdu) {
  const std::size_t length = pdu.size() + 1;
  std::vector<std::uint8_t> out{
      0x12, 0x34, 0, 0, static_cast<std::uint8_t>(length >> 8), static_cast<std::uint8_t>(length & 0xff), 0xff};
  for (std::uint8_t b : pdu)  // (not insert(): GCC 12 -O3 warns falsely on it)
    out.push_back(b);
  return out;
}

ModbusException check(const std::vector<std::uint8_t>& frame) { return check_request(frame, kPolicy).exception; }

std::size_t header_size(std::vector<std::uint8_t> h) {
  h.resize(7);
  return mbap_frame_size(std::span<const std::uint8_t, 7>(h.data(), 7));
}

}  // namespace

TEST(RequestGuard, MbapHeader) {
  EXPECT_EQ(header_size({0, 1, 0, 0, 0, 6, 1}), 12u);
  EXPECT_EQ(header_size({0, 1, 0, 1, 0, 6, 1}), 0u) << "protocol id must be 0";
  EXPECT_EQ(header_size({0, 1, 0, 0, 0, 1, 1}), 0u) << "length must cover unit id and function";
  EXPECT_EQ(header_size({0, 1, 0, 0, 0, 0, 1}), 0u);
  EXPECT_EQ(header_size({0, 1, 0, 0, 0, 254, 1}), 260u);
  EXPECT_EQ(header_size({0, 1, 0, 0, 0, 255, 1}), 0u) << "ADU would exceed 260 bytes";
  EXPECT_EQ(header_size({0, 1, 0, 0, 0xff, 0xff, 1}), 0u);
}

TEST(RequestGuard, ReadHoldingRegisters) {
  EXPECT_EQ(check(adu({0x03, 0, 0, 0, 64})), ModbusException::None);
  EXPECT_EQ(check(adu({0x04, 0, 8, 0, 28})), ModbusException::None);
  EXPECT_EQ(check(adu({0x03, 0, 0, 0, 65})), ModbusException::IllegalDataAddress);
  EXPECT_EQ(check(adu({0x03, 0, 63, 0, 2})), ModbusException::IllegalDataAddress);
  EXPECT_EQ(check(adu({0x03, 0xff, 0xff, 0, 1})), ModbusException::IllegalDataAddress);
  EXPECT_EQ(check(adu({0x03, 0, 0, 0, 0})), ModbusException::IllegalDataValue);
  EXPECT_EQ(check(adu({0x03, 0, 0, 0, 126})), ModbusException::IllegalDataValue);
  EXPECT_EQ(check(adu({0x03, 0, 0, 0})), ModbusException::IllegalDataValue) << "short PDU";
  EXPECT_EQ(check(adu({0x03, 0, 0, 0, 1, 0})), ModbusException::IllegalDataValue) << "long PDU";
}

TEST(RequestGuard, WriteSingleRegister) {
  const auto frame = adu({0x06, 0, 1, 0x12, 0x34});
  const GuardVerdict ok = check_request(frame, kPolicy);
  EXPECT_EQ(ok.exception, ModbusException::None);
  EXPECT_EQ(ok.write.address, 1);
  EXPECT_EQ(ok.write.count, 1);
  EXPECT_EQ(ok.write.values[0], 0x12);
  EXPECT_EQ(check(adu({0x06, 0, 8, 0, 1})), ModbusException::IllegalDataAddress) << "status is read-only";
  EXPECT_EQ(check(adu({0x06, 0, 4, 0, 1})), ModbusException::IllegalDataAddress) << "reserved";
  EXPECT_EQ(check(adu({0x06, 0, 1, 0})), ModbusException::IllegalDataValue);
}

TEST(RequestGuard, WriteMultipleRegisters) {
  const auto frame = adu({0x10, 0, 0, 0, 4, 8, 0, 1, 0, 7, 0, 3, 0, 0});
  const GuardVerdict ok = check_request(frame, kPolicy);
  EXPECT_EQ(ok.exception, ModbusException::None);
  EXPECT_EQ(ok.write.address, 0);
  EXPECT_EQ(ok.write.count, 4);
  EXPECT_EQ(ok.write.values, frame.data() + 13);
  EXPECT_EQ(check(adu({0x10, 0, 0, 0, 2, 2, 0, 1})), ModbusException::IllegalDataValue)
      << "byte count says 2, quantity says 2 registers";
  EXPECT_EQ(check(adu({0x10, 0, 0, 0, 2, 4, 0, 1})), ModbusException::IllegalDataValue)
      << "byte count 4 but only 2 data bytes present";
  EXPECT_EQ(check(adu({0x10, 0, 0, 0, 1, 2, 0, 1, 9, 9})), ModbusException::IllegalDataValue)
      << "trailing bytes beyond the byte count";
  EXPECT_EQ(check(adu({0x10, 0, 0, 0, 0, 0})), ModbusException::IllegalDataValue);
  EXPECT_EQ(check(adu({0x10, 0, 3, 0, 2, 4, 0, 1, 0, 2})), ModbusException::IllegalDataAddress);
  EXPECT_EQ(check(adu({0x10, 0, 0})), ModbusException::IllegalDataValue);
}

TEST(RequestGuard, ReadWriteMultipleRegisters) {
  // read 8..35, write 1..2
  EXPECT_EQ(check(adu({0x17, 0, 8, 0, 28, 0, 1, 0, 2, 4, 0, 5, 0, 6})), ModbusException::None);
  // CVE-2022-0367 shape: write quantity and byte count disagree.
  EXPECT_EQ(check(adu({0x17, 0, 0, 0, 1, 0, 0, 0, 0x79, 2, 0, 0})), ModbusException::IllegalDataValue);
  EXPECT_EQ(check(adu({0x17, 0, 0, 0, 1, 0, 0, 0, 1, 2})), ModbusException::IllegalDataValue)
      << "byte count 2 but no data";
  EXPECT_EQ(check(adu({0x17, 0, 0, 0, 1, 0, 0, 0, 0, 0})), ModbusException::IllegalDataValue) << "zero write quantity";
  EXPECT_EQ(check(adu({0x17, 0, 0, 0, 126, 0, 0, 0, 1, 2, 0, 0})), ModbusException::IllegalDataValue);
  EXPECT_EQ(check(adu({0x17, 0, 60, 0, 8, 0, 0, 0, 1, 2, 0, 0})), ModbusException::IllegalDataAddress);
  EXPECT_EQ(check(adu({0x17, 0, 0, 0, 1, 0xff, 0xff, 0, 1, 2, 0, 0})), ModbusException::IllegalDataAddress)
      << "write start far outside the map";
  EXPECT_EQ(check(adu({0x17, 0, 0, 0, 1, 0, 0})), ModbusException::IllegalDataValue) << "short";
}

TEST(RequestGuard, UnsupportedFunctions) {
  for (std::uint8_t fc : {0x01, 0x02, 0x05, 0x07, 0x08, 0x0b, 0x0f, 0x11, 0x14, 0x16, 0x2b, 0x83, 0xff}) {
    const GuardVerdict v = check_request(adu({fc, 0, 0, 0, 1}), kPolicy);
    EXPECT_EQ(v.exception, ModbusException::IllegalFunction) << int(fc);
    EXPECT_EQ(v.function, fc);
  }
  // FC 0x07 / 0x11 with no data at all (the 8-byte frame of libmodbus issue #837).
  EXPECT_EQ(check(adu({0x07})), ModbusException::IllegalFunction);
  EXPECT_EQ(check(adu({0x03})), ModbusException::IllegalDataValue);
}

// Every frame of every size up to 20 bytes from random bytes: the guard must never read
// outside the frame (ASan checks that) and must only ever pass well-formed requests.
TEST(RequestGuard, RandomFramesNeverPassMalformed) {
  std::uint32_t state = 12345;
  const auto next = [&] {
    state = state * 1664525u + 1013904223u;
    return static_cast<std::uint8_t>(state >> 24);
  };
  for (int i = 0; i < 200000; ++i) {
    std::vector<std::uint8_t> frame(7 + 1 + next() % 20);
    for (auto& b : frame) b = next();
    frame[7] = std::array<std::uint8_t, 6>{0x03, 0x04, 0x06, 0x10, 0x17, 0x2b}[next() % 6];
    const GuardVerdict v = check_request(frame, kPolicy);
    if (v.exception != ModbusException::None) continue;
    const std::size_t pdu = frame.size() - 7;
    switch (frame[7]) {
      case 0x03:
      case 0x04:
      case 0x06:
        ASSERT_EQ(pdu, 5u);
        break;
      case 0x10:
        ASSERT_EQ(pdu, 6u + frame[12]);
        ASSERT_EQ(frame[12], 2 * v.write.count);
        ASSERT_LE(v.write.address + v.write.count, 4);
        break;
      case 0x17:
        ASSERT_EQ(pdu, 10u + frame[16]);
        ASSERT_EQ(frame[16], 2 * v.write.count);
        break;
      default:
        FAIL() << "unsupported function passed";
    }
  }
}

// The map-v2 policy: control block and robot pose block writable, nothing in between. Compared
// on every (address, count) with the obvious per-register check.
TEST(RequestGuard, TwoWritableRangesMatchThePerRegisterRule) {
  constexpr RegisterPolicy two{64, 0, 4, 36, 50};
  const auto writable_register = [](unsigned a) { return a < 4 || (a >= 36 && a < 50); };
  for (unsigned address = 0; address < 70; ++address) {
    for (unsigned count = 1; count <= 20; ++count) {
      bool one_range = false;
      for (const auto& [b, e] : {std::pair{0u, 4u}, std::pair{36u, 50u}}) {
        bool inside = true;
        for (unsigned a = address; a < address + count; ++a) inside = inside && writable_register(a) && a >= b && a < e;
        one_range = one_range || inside;
      }
      std::vector<std::uint8_t> pdu{0x10,
                                    0,
                                    static_cast<std::uint8_t>(address),
                                    0,
                                    static_cast<std::uint8_t>(count),
                                    static_cast<std::uint8_t>(2 * count)};
      for (unsigned i = 0; i < 2 * count; ++i) pdu.push_back(0);
      const GuardVerdict v = check_request(adu(pdu), two);
      EXPECT_EQ(v.exception == ModbusException::None, one_range) << "address " << address << " count " << count;
      if (one_range) {
        EXPECT_EQ(v.write.address, address);
        EXPECT_EQ(v.write.count, count);
      } else {
        EXPECT_EQ(v.exception, ModbusException::IllegalDataAddress);
      }
    }
    // FC 0x06 on one register.
    const GuardVerdict single = check_request(adu({0x06, 0, static_cast<std::uint8_t>(address), 0, 1}), two);
    EXPECT_EQ(single.exception == ModbusException::None, writable_register(address)) << "address " << address;
  }
  // The single-range policy (map v1) still refuses the pose block.
  EXPECT_EQ(check(adu({0x06, 0, 36, 0, 1})), ModbusException::IllegalDataAddress);
}
