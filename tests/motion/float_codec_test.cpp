#include "motion/float_codec.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

using namespace mfcd::motion;

// The register values docs/register-map.md gives PLC programmers for 123456.0f.
TEST(FloatCodec, TestVectorABCD) {
  const auto words = encode_float(123456.0f, WordOrder::ABCD);
  EXPECT_EQ(words[0], 0x47F1);
  EXPECT_EQ(words[1], 0x2000);
  EXPECT_EQ(decode_float(0x47F1, 0x2000, WordOrder::ABCD), 123456.0f);
}

TEST(FloatCodec, TestVectorCDAB) {
  const auto words = encode_float(123456.0f, WordOrder::CDAB);
  EXPECT_EQ(words[0], 0x2000);
  EXPECT_EQ(words[1], 0x47F1);
  EXPECT_EQ(decode_float(0x2000, 0x47F1, WordOrder::CDAB), 123456.0f);
}

// Slow twin: lay the float out as big-endian bytes A B C D by hand and pick the words.
static std::array<std::uint16_t, 2> reference_encode(float value, WordOrder order) {
  std::uint32_t bits;
  std::memcpy(&bits, &value, 4);
  const std::uint8_t a = bits >> 24, b = (bits >> 16) & 0xff, c = (bits >> 8) & 0xff, d = bits & 0xff;
  const std::uint16_t ab = static_cast<std::uint16_t>(a * 256 + b);
  const std::uint16_t cd = static_cast<std::uint16_t>(c * 256 + d);
  return order == WordOrder::ABCD ? std::array<std::uint16_t, 2>{ab, cd} : std::array<std::uint16_t, 2>{cd, ab};
}

TEST(FloatCodec, MatchesByteLayoutOnRandomBitPatterns) {
  std::mt19937 rng(6);
  std::uniform_int_distribution<std::uint32_t> any;
  for (int i = 0; i < 100000; ++i) {
    const std::uint32_t bits = any(rng);
    float value;
    std::memcpy(&value, &bits, 4);
    for (WordOrder order : {WordOrder::ABCD, WordOrder::CDAB}) {
      const auto fast = encode_float(value, order);
      ASSERT_EQ(fast, reference_encode(value, order)) << std::hex << bits;
      const float back = decode_float(fast[0], fast[1], order);
      std::uint32_t back_bits;
      std::memcpy(&back_bits, &back, 4);
      ASSERT_EQ(back_bits, bits);  // bit-exact, NaN payloads included
    }
  }
}

TEST(FloatCodec, SpecialValues) {
  EXPECT_EQ(encode_float(0.0f, WordOrder::ABCD), (std::array<std::uint16_t, 2>{0, 0}));
  EXPECT_EQ(encode_float(-0.0f, WordOrder::ABCD), (std::array<std::uint16_t, 2>{0x8000, 0}));
  EXPECT_EQ(encode_float(1.0f, WordOrder::ABCD), (std::array<std::uint16_t, 2>{0x3F80, 0}));
  EXPECT_EQ(encode_float(-2.5f, WordOrder::CDAB), (std::array<std::uint16_t, 2>{0, 0xC020}));
  EXPECT_EQ(encode_float(std::numeric_limits<float>::infinity(), WordOrder::ABCD),
            (std::array<std::uint16_t, 2>{0x7F80, 0}));
}

TEST(FloatCodec, ParseWordOrder) {
  EXPECT_EQ(parse_word_order("ABCD"), WordOrder::ABCD);
  EXPECT_EQ(parse_word_order("cdab"), WordOrder::CDAB);
  EXPECT_FALSE(parse_word_order("BADC").has_value());
  EXPECT_EQ(to_string(WordOrder::CDAB), "CDAB");
}
