#pragma once
// Whitespace-separated words of a text mesh file (ASCII STL, OBJ), with the line each came from
// for error messages. Reads from a string it does not own; allocates nothing but the words it
// returns and its messages.

#include <cstddef>
#include <string>
#include <string_view>
#include <utility>

namespace mfcd::vision {

class TextTokens {
 public:
  TextTokens(std::string_view text, std::string source) : text_(text), source_(std::move(source)) {}

  // The next word; std::runtime_error at the end of the text.
  std::string word();
  // The next word must be `w` (else std::runtime_error naming both).
  void expect(std::string_view w);
  // The next word as a finite float (else std::runtime_error naming it).
  float number();
  // Past the end of the current line.
  void rest_of_line();
  // Only whitespace is left.
  bool at_end();
  // The next line's text (without its end), false at the end of the text.
  bool line(std::string_view& out);
  // Throws std::runtime_error "<source>:<line>: <what>".
  [[noreturn]] void fail(const std::string& what) const;

  // `w` as a finite float; false when it is not one (trailing characters, out of range, nan, inf).
  static bool parse_float(std::string_view w, float& out);

 private:
  void skip_space();
  std::string_view text_;
  std::string source_;
  size_t pos_ = 0;
  int line_ = 1;
};

}  // namespace mfcd::vision
