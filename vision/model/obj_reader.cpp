#include "vision/model/obj_reader.hpp"

#include <charconv>
#include <cstdint>
#include <fstream>
#include <iterator>
#include <limits>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "vision/model/text_tokens.hpp"

namespace mfcd::vision {

namespace {

bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

// The line's next blank-separated word, empty at its end.
std::string_view next_word(std::string_view& line) {
  size_t i = 0;
  while (i < line.size() && is_blank(line[i])) ++i;
  size_t j = i;
  while (j < line.size() && !is_blank(line[j])) ++j;
  const std::string_view w = line.substr(i, j - i);
  line.remove_prefix(j);
  return w;
}

// "<before>'<word>'<after>", appended piece by piece (GCC 12's -Wrestrict misfires on a chain of
// operator+ at -O3).
std::string quoted(const char* before, std::string_view word, const char* after) {
  std::string s(before);
  s.append("'").append(word).append("'").append(after);
  return s;
}

// A face corner's vertex index (the part before any '/'), 0-based, resolved against the `count`
// vertices read so far.
uint32_t corner_index(std::string_view corner, size_t count, TextTokens& in) {
  const std::string_view v = corner.substr(0, corner.find('/'));
  int64_t i = 0;
  const auto [end, ec] = std::from_chars(v.data(), v.data() + v.size(), i);
  if (ec != std::errc() || end != v.data() + v.size() || v.empty())
    in.fail(quoted("face corner ", corner, " has no vertex index"));
  if (i == 0) in.fail("vertex index 0 (OBJ counts from 1)");
  const int64_t resolved = i > 0 ? i - 1 : static_cast<int64_t>(count) + i;
  if (resolved < 0) in.fail("vertex index " + std::to_string(i) + " is before the first vertex");
  if (resolved > int64_t{std::numeric_limits<uint32_t>::max()})
    in.fail("vertex index " + std::to_string(i) + " is past 2^32");
  return static_cast<uint32_t>(resolved);
}

}  // namespace

Mesh read_obj(const std::filesystem::path& file, float scale) {
  const std::string src = file.string();
  std::ifstream f(file, std::ios::binary);
  if (!f) throw std::runtime_error(src + ": cannot open");
  const std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  TextTokens in(text, src);
  Mesh m;
  m.name = file.stem().string();
  std::vector<uint32_t> corners;
  for (std::string_view line; in.line(line);) {
    line = line.substr(0, line.find('#'));
    const std::string_view key = next_word(line);
    if (key == "v") {
      float xyz[3];
      for (float& c : xyz) {
        const std::string_view w = next_word(line);
        if (w.empty()) in.fail("a vertex needs x, y and z");
        if (!TextTokens::parse_float(w, c)) in.fail(quoted("", w, " is not a finite number"));
      }
      m.vertices.emplace_back(xyz[0] * scale, xyz[1] * scale, xyz[2] * scale);
    } else if (key == "f") {
      corners.clear();
      for (std::string_view w = next_word(line); !w.empty(); w = next_word(line))
        corners.push_back(corner_index(w, m.vertices.size(), in));
      if (corners.size() < 3) in.fail("a face needs at least three corners");
      for (size_t k = 1; k + 1 < corners.size(); ++k) m.triangles.push_back({corners[0], corners[k], corners[k + 1]});
    }
  }
  return m;
}

}  // namespace mfcd::vision
