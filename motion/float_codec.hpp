// IEEE-754 float32 <-> two Modbus registers, with the word order a PLC expects.
//
// libmodbus 3.1.6's modbus_get_float_*/modbus_set_float_* helpers mix host and network byte
// order and give wrong results on little-endian hosts, so mfcd encodes floats itself here.
#pragma once

#include <array>
#include <bit>
#include <cstdint>
#include <optional>
#include <string_view>

namespace mfcd::motion {

// ABCD: big-endian 32-bit value, high word in the lower register (Modicon / Siemens default).
// CDAB: word-swapped, low word in the lower register (common on Schneider, some Allen-Bradley setups).
// Within each register the two bytes always travel high byte first, as Modbus requires.
enum class WordOrder : std::uint16_t { ABCD = 0, CDAB = 1 };

constexpr std::array<std::uint16_t, 2> encode_float(float value, WordOrder order) noexcept {
  const auto bits = std::bit_cast<std::uint32_t>(value);
  const auto high = static_cast<std::uint16_t>(bits >> 16);
  const auto low = static_cast<std::uint16_t>(bits & 0xffffu);
  if (order == WordOrder::ABCD) return {high, low};
  return {low, high};
}

constexpr float decode_float(std::uint16_t first, std::uint16_t second, WordOrder order) noexcept {
  const std::uint32_t high = order == WordOrder::ABCD ? first : second;
  const std::uint32_t low = order == WordOrder::ABCD ? second : first;
  return std::bit_cast<float>((high << 16) | low);
}

std::optional<WordOrder> parse_word_order(std::string_view text) noexcept;
std::string_view to_string(WordOrder order) noexcept;

}  // namespace mfcd::motion
