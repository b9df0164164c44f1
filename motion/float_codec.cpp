#include "motion/float_codec.hpp"

namespace mfcd::motion {

std::optional<WordOrder> parse_word_order(std::string_view text) noexcept {
  if (text == "ABCD" || text == "abcd") return WordOrder::ABCD;
  if (text == "CDAB" || text == "cdab") return WordOrder::CDAB;
  return std::nullopt;
}

std::string_view to_string(WordOrder order) noexcept { return order == WordOrder::ABCD ? "ABCD" : "CDAB"; }

}  // namespace mfcd::motion
