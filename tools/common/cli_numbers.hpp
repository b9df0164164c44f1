#pragma once
// Numeric option values for the command-line tools: the whole text must be the number, and a
// bad value is refused naming the option ("--views 'x' is not an integer").
#include <cmath>
#include <stdexcept>
#include <string>

namespace mfcd::tools {

inline int parse_int(const std::string& option, const std::string& text) {
  size_t used = 0;
  int n = 0;
  try {
    n = std::stoi(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (text.empty() || used != text.size()) throw std::invalid_argument(option + " '" + text + "' is not an integer");
  return n;
}

inline double parse_double(const std::string& option, const std::string& text) {
  size_t used = 0;
  double d = 0;
  try {
    d = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (text.empty() || used != text.size() || !std::isfinite(d))
    throw std::invalid_argument(option + " '" + text + "' is not a number");
  return d;
}

}  // namespace mfcd::tools
