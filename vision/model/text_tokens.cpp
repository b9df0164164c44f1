#include "vision/model/text_tokens.hpp"

#include <charconv>
#include <cmath>
#include <stdexcept>

namespace mfcd::vision {

namespace {

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v'; }

}  // namespace

void TextTokens::skip_space() {
  while (pos_ < text_.size() && is_space(text_[pos_])) {
    if (text_[pos_] == '\n') ++line_;
    ++pos_;
  }
}

std::string TextTokens::word() {
  skip_space();
  if (pos_ >= text_.size()) fail("unexpected end of file");
  const size_t start = pos_;
  while (pos_ < text_.size() && !is_space(text_[pos_])) ++pos_;
  return std::string(text_.substr(start, pos_ - start));
}

void TextTokens::expect(std::string_view w) {
  const std::string got = word();
  if (got != w) fail("expected '" + std::string(w) + "', found '" + got + "'");
}

bool TextTokens::parse_float(std::string_view w, float& out) {
  if (!w.empty() && w.front() == '+') w.remove_prefix(1);  // from_chars takes no '+'
  const auto [end, ec] = std::from_chars(w.data(), w.data() + w.size(), out);
  return ec == std::errc() && end == w.data() + w.size() && std::isfinite(out);
}

float TextTokens::number() {
  const std::string w = word();
  float v = 0;
  if (!parse_float(w, v)) fail("'" + w + "' is not a finite number");
  return v;
}

void TextTokens::rest_of_line() {
  while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
}

bool TextTokens::at_end() {
  skip_space();
  return pos_ >= text_.size();
}

bool TextTokens::line(std::string_view& out) {
  if (pos_ >= text_.size()) return false;
  if (pos_ > 0) ++line_;  // the line before ended with the '\n' consumed below
  const size_t end = text_.find('\n', pos_);
  const size_t stop = end == std::string_view::npos ? text_.size() : end;
  out = text_.substr(pos_, stop - pos_);
  pos_ = end == std::string_view::npos ? text_.size() : end + 1;
  return true;
}

void TextTokens::fail(const std::string& what) const {
  throw std::runtime_error(source_ + ":" + std::to_string(line_) + ": " + what);
}

}  // namespace mfcd::vision
