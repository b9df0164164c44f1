#include "vision/model/ply_reader.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace mfcd::vision {

namespace fs = std::filesystem;

namespace {

enum class Type { i8, u8, i16, u16, i32, u32, f32, f64 };
enum class Format { ascii, binary_little_endian, binary_big_endian };

std::optional<Type> type_named(const std::string& s) {
  if (s == "char" || s == "int8") return Type::i8;
  if (s == "uchar" || s == "uint8") return Type::u8;
  if (s == "short" || s == "int16") return Type::i16;
  if (s == "ushort" || s == "uint16") return Type::u16;
  if (s == "int" || s == "int32") return Type::i32;
  if (s == "uint" || s == "uint32") return Type::u32;
  if (s == "float" || s == "float32") return Type::f32;
  if (s == "double" || s == "float64") return Type::f64;
  return std::nullopt;
}

size_t size_of(Type t) {
  switch (t) {
    case Type::i8:
    case Type::u8:
      return 1;
    case Type::i16:
    case Type::u16:
      return 2;
    case Type::i32:
    case Type::u32:
    case Type::f32:
      return 4;
    case Type::f64:
      return 8;
  }
  return 1;
}

struct Property {
  std::string name;
  Type type = Type::f32;
  bool list = false;
  Type count_type = Type::u8;
};

struct Element {
  std::string name;
  uint64_t count = 0;
  std::vector<Property> properties;
};

[[noreturn]] void fail(const fs::path& file, const std::string& reason) {
  throw std::runtime_error(file.string() + ": " + reason);
}

// The values of the body, one at a time, in the file's format; every read checks that the file
// still holds it.
class Body {
 public:
  Body(const std::string& data, size_t start, Format format, const fs::path& file)
      : data_(data), pos_(start), format_(format), file_(file) {}

  double next(Type t) {
    if (format_ == Format::ascii) return next_text();
    const size_t n = size_of(t);
    if (pos_ + n > data_.size()) fail(file_, "truncated: the body ends inside a value at byte " + std::to_string(pos_));
    unsigned char b[8];
    std::memcpy(b, data_.data() + pos_, n);
    pos_ += n;
    const bool file_little = format_ == Format::binary_little_endian;
    if (file_little != (std::endian::native == std::endian::little)) std::reverse(b, b + n);
    switch (t) {
      case Type::i8:
        return static_cast<int8_t>(b[0]);
      case Type::u8:
        return b[0];
      case Type::i16:
        return scalar<int16_t>(b);
      case Type::u16:
        return scalar<uint16_t>(b);
      case Type::i32:
        return scalar<int32_t>(b);
      case Type::u32:
        return scalar<uint32_t>(b);
      case Type::f32:
        return scalar<float>(b);
      case Type::f64:
        return scalar<double>(b);
    }
    return 0;
  }

  size_t remaining() const { return data_.size() - std::min(pos_, data_.size()); }

 private:
  template <class T>
  static double scalar(const unsigned char* b) {
    T v;
    std::memcpy(&v, b, sizeof v);
    return static_cast<double>(v);
  }

  double next_text() {
    const char* begin = data_.c_str() + pos_;
    char* end = nullptr;
    const double v = std::strtod(begin, &end);
    if (end == begin) {
      const size_t line =
          1 + static_cast<size_t>(std::count(data_.begin(), data_.begin() + static_cast<long>(pos_), '\n'));
      const bool at_end = std::all_of(begin, data_.c_str() + data_.size(),
                                      [](char c) { return std::isspace(static_cast<unsigned char>(c)); });
      fail(file_, at_end ? "truncated: the body ends before all elements are read (line " + std::to_string(line) + ")"
                         : "line " + std::to_string(line) + ": expected a number");
    }
    pos_ = static_cast<size_t>(end - data_.c_str());
    return v;
  }

  const std::string& data_;
  size_t pos_;
  Format format_;
  const fs::path& file_;
};

struct Header {
  Format format = Format::ascii;
  std::vector<Element> elements;
  size_t body_start = 0;
};

Header parse_header(const std::string& data, const fs::path& file) {
  if (data.compare(0, 3, "ply") != 0) fail(file, "not a PLY file (it does not start with 'ply')");
  const size_t end = data.find("end_header");
  if (end == std::string::npos) fail(file, "no 'end_header' line");
  Header h;
  size_t eol = data.find('\n', end);
  h.body_start = eol == std::string::npos ? data.size() : eol + 1;
  std::istringstream lines(data.substr(0, end));
  std::string line;
  bool have_format = false;
  int n = 0;
  while (std::getline(lines, line)) {
    ++n;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream w(line);
    std::string key;
    w >> key;
    const std::string where = "header line " + std::to_string(n) + ": ";
    if (key.empty() || key == "ply" || key == "comment" || key == "obj_info") continue;
    if (key == "format") {
      std::string f, version;
      w >> f >> version;
      if (f == "ascii")
        h.format = Format::ascii;
      else if (f == "binary_little_endian")
        h.format = Format::binary_little_endian;
      else if (f == "binary_big_endian")
        h.format = Format::binary_big_endian;
      else
        fail(file, where + "unknown format '" + f + "'");
      have_format = true;
    } else if (key == "element") {
      Element e;
      long long count = -1;
      w >> e.name >> count;
      if (e.name.empty() || count < 0) fail(file, where + "expected 'element NAME COUNT'");
      e.count = static_cast<uint64_t>(count);
      h.elements.push_back(std::move(e));
    } else if (key == "property") {
      if (h.elements.empty()) fail(file, where + "a property before any element");
      Property p;
      std::string t;
      w >> t;
      if (t == "list") {
        std::string ct, vt;
        w >> ct >> vt >> p.name;
        const auto c = type_named(ct), v = type_named(vt);
        if (!c || !v || p.name.empty()) fail(file, where + "expected 'property list COUNT_TYPE TYPE NAME'");
        if (*c == Type::f32 || *c == Type::f64) fail(file, where + "a list count must be an integer type");
        p.list = true, p.count_type = *c, p.type = *v;
      } else {
        w >> p.name;
        const auto v = type_named(t);
        if (!v || p.name.empty()) fail(file, where + "unknown property type '" + t + "'");
        p.type = *v;
      }
      h.elements.back().properties.push_back(p);
    } else {
      fail(file, where + "unknown keyword '" + key + "'");
    }
  }
  if (!have_format) fail(file, "no 'format' line in the header");
  return h;
}

// The fewest bytes one instance of `e` takes in the body: a count the file cannot hold is refused
// before anything is allocated for it.
size_t min_bytes(const Element& e, Format format) {
  size_t b = 0;
  for (const auto& p : e.properties)
    b += format == Format::ascii ? 2 : (p.list ? size_of(p.count_type) : size_of(p.type));
  return std::max<size_t>(b, 1);
}

}  // namespace

Mesh read_ply(const fs::path& file, float scale) {
  std::ifstream in(file, std::ios::binary);
  if (!in) fail(file, "cannot open");
  const std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const Header h = parse_header(data, file);
  Body body(data, h.body_start, h.format, file);

  const Element* vertex_element = nullptr;
  for (const auto& e : h.elements) {
    if (e.properties.empty() && e.count > 0) fail(file, "element '" + e.name + "' has instances but no properties");
    if (e.count > body.remaining() / min_bytes(e, h.format))
      fail(file, "element '" + e.name + "' declares " + std::to_string(e.count) + " instances, more than the " +
                     std::to_string(body.remaining()) + "-byte body can hold");
    if (e.name == "vertex") vertex_element = &e;
  }
  if (!vertex_element) fail(file, "no 'vertex' element");
  int xyz[3] = {-1, -1, -1};
  for (size_t i = 0; i < vertex_element->properties.size(); ++i)
    for (int k = 0; k < 3; ++k)
      if (!vertex_element->properties[i].list && vertex_element->properties[i].name == std::string(1, "xyz"[k]))
        xyz[k] = static_cast<int>(i);
  if (xyz[0] < 0 || xyz[1] < 0 || xyz[2] < 0) fail(file, "the 'vertex' element has no x, y and z properties");
  const uint64_t n_vertices = vertex_element->count;

  Mesh mesh;
  mesh.name = file.stem().string();
  for (const auto& e : h.elements) {
    const bool is_vertex = &e == vertex_element, is_face = e.name == "face";
    if (is_vertex) mesh.vertices.reserve(e.count);
    std::vector<uint32_t> polygon;
    for (uint64_t i = 0; i < e.count; ++i) {
      cv::Vec3f p(0, 0, 0);
      for (size_t k = 0; k < e.properties.size(); ++k) {
        const Property& prop = e.properties[k];
        if (!prop.list) {
          const double v = body.next(prop.type);
          for (int a = 0; a < 3; ++a)
            if (is_vertex && static_cast<int>(k) == xyz[a]) p[a] = static_cast<float>(v) * scale;
          continue;
        }
        const double count = body.next(prop.count_type);
        if (count < 0 || count != std::floor(count) || count > 1e6)
          fail(file, e.name + " " + std::to_string(i) + ": list '" + prop.name + "' has a bad length");
        const bool indices = is_face && (prop.name == "vertex_indices" || prop.name == "vertex_index");
        polygon.clear();
        for (int j = 0; j < static_cast<int>(count); ++j) {
          const double v = body.next(prop.type);
          if (!indices) continue;
          if (!(v >= 0 && v < static_cast<double>(n_vertices) && v == std::floor(v)))
            fail(file, "face " + std::to_string(i) + ": vertex index " + std::to_string(v) + " is not one of the " +
                           std::to_string(n_vertices) + " vertices");
          polygon.push_back(static_cast<uint32_t>(v));
        }
        for (size_t j = 2; j < polygon.size(); ++j) mesh.triangles.push_back({polygon[0], polygon[j - 1], polygon[j]});
      }
      if (is_vertex) mesh.vertices.push_back(p);
    }
  }
  return mesh;
}

}  // namespace mfcd::vision
