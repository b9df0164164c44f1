#pragma once
// Numbers written as text in configuration and calibration files (YAML scalars): the whole text
// must be the number, so "12abc", "", "1e3" (for an integer) or a value past the type are refused
// rather than read in part.

#include <cerrno>
#include <cstdlib>
#include <limits>
#include <optional>
#include <string>

namespace mfcd::vision {

// A base-10 int, or nothing when `text` is not exactly one (empty, trailing characters, out of
// int's range).
inline std::optional<int> parse_int(const std::string& text) {
  errno = 0;
  char* end = nullptr;
  const long long v = std::strtoll(text.c_str(), &end, 10);
  if (text.empty() || *end != '\0' || errno == ERANGE || v < std::numeric_limits<int>::min() ||
      v > std::numeric_limits<int>::max())
    return std::nullopt;
  return static_cast<int>(v);
}

}  // namespace mfcd::vision
