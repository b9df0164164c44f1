#include "vision/model/stl_reader.hpp"

#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "vision/model/text_tokens.hpp"

namespace mfcd::vision {

namespace {

constexpr size_t kBinaryHeader = 80 + 4, kBinaryTriangle = 50;

float little_endian_float(const char* p) {
  uint32_t u = 0;
  for (int i = 3; i >= 0; --i) u = (u << 8) | static_cast<unsigned char>(p[i]);
  float f;
  std::memcpy(&f, &u, sizeof f);
  return f;
}

// The triangle count a binary file's header states (little-endian, after the 80-byte header).
uint32_t stated_count(const std::string& bytes) {
  uint32_t count = 0;
  for (int i = 3; i >= 0; --i) count = (count << 8) | static_cast<unsigned char>(bytes[80 + static_cast<size_t>(i)]);
  return count;
}

// `bytes` holds exactly `count` triangles after the header.
Mesh read_binary(const std::string& bytes, uint32_t count, float scale) {
  Mesh m;
  m.vertices.reserve(size_t{count} * 3);
  m.triangles.reserve(count);
  for (size_t t = 0; t < count; ++t) {
    const char* p = bytes.data() + kBinaryHeader + t * kBinaryTriangle + 12;  // past the normal
    const auto base = static_cast<uint32_t>(m.vertices.size());
    for (int c = 0; c < 3; ++c, p += 12)
      m.vertices.emplace_back(little_endian_float(p) * scale, little_endian_float(p + 4) * scale,
                              little_endian_float(p + 8) * scale);
    m.triangles.push_back({base, base + 1, base + 2});
  }
  return m;
}

Mesh read_ascii(const std::string& text, const std::string& src, float scale) {
  TextTokens in(text, src);
  Mesh m;
  in.expect("solid");
  in.rest_of_line();  // the solid's name, if any
  while (true) {
    const std::string word = in.word();
    if (word == "endsolid") {
      in.rest_of_line();
      if (in.at_end()) break;
      in.expect("solid");
      in.rest_of_line();
      continue;
    }
    if (word != "facet") in.fail("expected 'facet' or 'endsolid', found '" + word + "'");
    in.rest_of_line();  // normal x y z
    in.expect("outer");
    in.expect("loop");
    const auto base = static_cast<uint32_t>(m.vertices.size());
    for (int c = 0; c < 3; ++c) {
      in.expect("vertex");
      const float x = in.number(), y = in.number(), z = in.number();
      m.vertices.emplace_back(x * scale, y * scale, z * scale);
    }
    in.expect("endloop");
    in.expect("endfacet");
    m.triangles.push_back({base, base + 1, base + 2});
  }
  return m;
}

}  // namespace

Mesh read_stl(const std::filesystem::path& file, float scale) {
  const std::string src = file.string();
  std::ifstream f(file, std::ios::binary);
  if (!f) throw std::runtime_error(src + ": cannot open");
  const std::string bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  const uint32_t count = bytes.size() >= kBinaryHeader ? stated_count(bytes) : 0;
  const bool binary = bytes.size() >= kBinaryHeader && bytes.size() == kBinaryHeader + size_t{count} * kBinaryTriangle;
  if (!binary && bytes.compare(0, 5, "solid") != 0)
    throw std::runtime_error(src + ": not an STL file (neither 84 + 50 bytes per triangle nor ASCII 'solid')");
  Mesh m = binary ? read_binary(bytes, count, scale) : read_ascii(bytes, src, scale);
  m.name = file.stem().string();
  return m;
}

}  // namespace mfcd::vision
