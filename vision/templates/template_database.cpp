#include "vision/templates/template_database.hpp"

#include "vision/common/rotation.hpp"

#include <zlib.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace mfcd::vision {

static_assert(std::endian::native == std::endian::little, "the .tdb format is little-endian; add byte swapping");

namespace {

constexpr char kMagic[8] = {'M', 'F', 'C', 'D', '-', 'T', 'D', 'B'};
constexpr uint32_t kHeaderBytes = 32;

class Writer {
 public:
  template <class T>
  void put(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    const auto* p = reinterpret_cast<const uint8_t*>(&v);
    bytes.insert(bytes.end(), p, p + sizeof(T));
  }
  void str(const std::string& s) {
    put(static_cast<uint32_t>(s.size()));
    bytes.insert(bytes.end(), s.begin(), s.end());
  }
  std::vector<uint8_t> bytes;
};

class Reader {
 public:
  Reader(const uint8_t* data, size_t size, const std::string& source) : p_(data), n_(size), source_(source) {}
  template <class T>
  T get(const char* what) {
    static_assert(std::is_trivially_copyable_v<T>);
    if (n_ - pos_ < sizeof(T)) fail(std::string("payload ends inside ") + what);
    T v;
    std::memcpy(&v, p_ + pos_, sizeof(T));
    pos_ += sizeof(T);
    return v;
  }
  // A count of items of `item_bytes` each: refused when the rest of the payload cannot hold them,
  // so a corrupt count never makes us allocate gigabytes.
  uint32_t count(const char* what, size_t item_bytes) {
    const auto c = get<uint32_t>(what);
    if (item_bytes > 0 && c > (n_ - pos_) / item_bytes)
      fail(std::string(what) + " = " + std::to_string(c) + " does not fit in the remaining payload");
    return c;
  }
  std::string str(const char* what) {
    const uint32_t len = count(what, 1);
    std::string s(reinterpret_cast<const char*>(p_ + pos_), len);
    pos_ += len;
    return s;
  }
  double finite(const char* what) {
    const double v = get<double>(what);
    if (!std::isfinite(v)) fail(std::string(what) + " is not finite");
    return v;
  }
  size_t remaining() const { return n_ - pos_; }
  [[noreturn]] void fail(const std::string& why) const {
    throw TemplateFileError(source_ + ": malformed template database (at payload byte " + std::to_string(pos_) +
                            "): " + why);
  }

 private:
  const uint8_t* p_;
  size_t n_, pos_ = 0;
  std::string source_;
};

// A symmetry: its kind (uint8) and order (int32). `what` names it in a refusal.
void put_symmetry(Writer& w, const PartSymmetry& s) {
  w.put<uint8_t>(static_cast<uint8_t>(s.kind));
  w.put<int32_t>(s.order);
}

PartSymmetry get_symmetry(Reader& r, const std::string& what) {
  PartSymmetry s;
  const auto kind = r.get<uint8_t>(what.c_str());
  if (kind > 2) r.fail("unknown " + what + " kind " + std::to_string(kind));
  s.kind = static_cast<PartSymmetry::Kind>(kind);
  s.order = r.get<int32_t>((what + " order").c_str());
  if (s.order < 1 || s.order > 360) r.fail(what + " order out of range");
  return s;
}

// The part's turns (MeshTurns): centroid and principal axes, then the symmetries and the
// alternatives, each a count and per turn its kind (uint8), rotation (9 doubles, row-major),
// pivot and axis (3 doubles each), order (int32) and share on the surface (double).
constexpr size_t kTurnBytes = 1 + 8 * (9 + 3 + 3) + 4 + 8;

void put_turns(Writer& w, const MeshTurns& t) {
  for (int i = 0; i < 3; ++i) w.put<double>(t.centroid_mm[i]);
  for (int i = 0; i < 9; ++i) w.put<double>(t.principal_axes.val[i]);
  for (const auto* list : {&t.symmetries, &t.alternatives}) {
    w.put(static_cast<uint32_t>(list->size()));
    for (const MeshTurn& m : *list) {
      w.put<uint8_t>(static_cast<uint8_t>(m.kind));
      for (int i = 0; i < 9; ++i) w.put<double>(m.R.val[i]);
      for (int i = 0; i < 3; ++i) w.put<double>(m.pivot_mm[i]);
      for (int i = 0; i < 3; ++i) w.put<double>(m.axis[i]);
      w.put<int32_t>(m.order);
      w.put<double>(m.on_surface);
    }
  }
}

// A rotation that is not one (not orthonormal, or a reflection) would place the turned pose
// anywhere: refused, as a corrupt file.
bool is_rotation(const cv::Matx33d& R) {
  return cv::norm(R.t() * R - cv::Matx33d::eye(), cv::NORM_INF) < 1e-6 && cv::determinant(R) > 0;
}

MeshTurns get_turns(Reader& r) {
  MeshTurns t;
  for (int i = 0; i < 3; ++i) t.centroid_mm[i] = r.finite("turns centroid");
  for (int i = 0; i < 9; ++i) t.principal_axes.val[i] = r.finite("turns principal axes");
  if (!is_rotation(t.principal_axes)) r.fail("turns: principal axes are not a rotation");
  for (auto* list : {&t.symmetries, &t.alternatives}) {
    list->resize(r.count("turn count", kTurnBytes));
    for (MeshTurn& m : *list) {
      const auto kind = r.get<uint8_t>("turn kind");
      if (kind > static_cast<uint8_t>(MeshTurn::Kind::phase)) r.fail("unknown turn kind " + std::to_string(kind));
      m.kind = static_cast<MeshTurn::Kind>(kind);
      for (int i = 0; i < 9; ++i) m.R.val[i] = r.finite("turn rotation");
      if (!is_rotation(m.R)) r.fail("turn rotation is not a rotation");
      for (int i = 0; i < 3; ++i) m.pivot_mm[i] = r.finite("turn pivot");
      for (int i = 0; i < 3; ++i) m.axis[i] = r.finite("turn axis");
      if (std::abs(cv::norm(m.axis) - 1) > 1e-6) r.fail("turn axis is not a unit vector");
      m.order = r.get<int32_t>("turn order");
      if (m.order < 0 || m.order > 360) r.fail("turn order " + std::to_string(m.order) + " out of range");
      m.on_surface = r.finite("turn share");
      if (m.on_surface < 0 || m.on_surface > 1) r.fail("turn share out of [0, 1]");
    }
  }
  return t;
}

// Why a database whose views are folded by a turn the part does not have is refused (on save
// and on load alike).
std::string unfolded_views(const TemplateDatabase& db) {
  return "views folded by " + db.views_symmetry.str() + ", which is not a symmetry of the part (" + db.symmetry.str() +
         ")";
}

void put_camera(Writer& w, const CameraConfig& c) {
  w.put<int32_t>(c.camera.image_size.width);
  w.put<int32_t>(c.camera.image_size.height);
  for (int i = 0; i < 9; ++i) w.put<double>(c.camera.K.val[i]);
  w.put(static_cast<uint32_t>(c.camera.distortion.size()));
  for (double d : c.camera.distortion) w.put(d);
  w.put(static_cast<uint32_t>(c.flashes.positions_mm.size()));
  for (const auto& p : c.flashes.positions_mm)
    for (int i = 0; i < 3; ++i) w.put<double>(p[i]);
  w.put<double>(c.working_distance_mm);
}

CameraConfig get_camera(Reader& r) {
  CameraConfig c;
  c.camera.image_size.width = r.get<int32_t>("image width");
  c.camera.image_size.height = r.get<int32_t>("image height");
  if (c.camera.image_size.width <= 0 || c.camera.image_size.height <= 0 || c.camera.image_size.width > 100000 ||
      c.camera.image_size.height > 100000)
    r.fail("image size " + std::to_string(c.camera.image_size.width) + "x" +
           std::to_string(c.camera.image_size.height) + " is not plausible");
  for (int i = 0; i < 9; ++i) c.camera.K.val[i] = r.finite("camera matrix");
  c.camera.distortion.resize(r.count("distortion count", 8));
  for (double& d : c.camera.distortion) d = r.finite("distortion");
  c.flashes.ring.reset();
  c.flashes.positions_mm.resize(r.count("flash count", 24));
  for (auto& p : c.flashes.positions_mm)
    for (int i = 0; i < 3; ++i) p[i] = r.finite("flash position");
  c.working_distance_mm = r.finite("working distance");
  return c;
}

void put_lines(Writer& w, const LineSet& s) {
  w.put<int32_t>(s.q);
  w.put<int32_t>(s.size.width);
  w.put<int32_t>(s.size.height);
  w.put<float>(s.origin.x);
  w.put<float>(s.origin.y);
  w.put(static_cast<uint32_t>(s.lines.size()));
  for (const auto& l : s.lines) {
    w.put(l.a.x), w.put(l.a.y), w.put(l.b.x), w.put(l.b.y);
    w.put<int32_t>(l.channel);
    w.put<int32_t>(l.support);
  }
}

LineSet get_lines(Reader& r, int q, bool oriented) {
  LineSet s;
  s.oriented = oriented;
  s.q = r.get<int32_t>("line set q");
  if (s.q != q) r.fail("a view's lines have q = " + std::to_string(s.q) + ", the database q = " + std::to_string(q));
  s.size.width = r.get<int32_t>("line set width");
  s.size.height = r.get<int32_t>("line set height");
  s.origin.x = r.get<float>("line set origin");
  s.origin.y = r.get<float>("line set origin");
  s.lines.resize(r.count("line count", 24));
  for (auto& l : s.lines) {
    l.a.x = r.get<float>("line"), l.a.y = r.get<float>("line");
    l.b.x = r.get<float>("line"), l.b.y = r.get<float>("line");
    l.channel = r.get<int32_t>("line channel");
    l.support = r.get<int32_t>("line support");
    if (!std::isfinite(l.a.x) || !std::isfinite(l.a.y) || !std::isfinite(l.b.x) || !std::isfinite(l.b.y))
      r.fail("a line endpoint is not finite");
    if (l.channel < 0 || l.channel >= q) r.fail("line channel " + std::to_string(l.channel) + " outside [0, q)");
  }
  return s;
}

std::vector<uint8_t> read_all(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw TemplateFileError(file.string() + ": cannot open template database");
  return std::vector<uint8_t>((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

uint32_t crc_of(const uint8_t* data, size_t size) {
  uLong crc = crc32(0L, Z_NULL, 0);
  while (size > 0) {
    const uInt chunk = static_cast<uInt>(std::min<size_t>(size, 1u << 30));
    crc = crc32(crc, data, chunk);
    data += chunk;
    size -= chunk;
  }
  return static_cast<uint32_t>(crc);
}

}  // namespace

PartSymmetry PartSymmetry::parse(const std::string& text) {
  PartSymmetry s;
  if (text.empty() || text == "none") return s;
  if (text == "z:inf") {
    s.kind = Kind::continuous_z;
    return s;
  }
  if (text.rfind("z:", 0) == 0) {
    try {
      size_t used = 0;
      const int n = std::stoi(text.substr(2), &used);
      if (used == text.size() - 2 && n >= 1 && n <= 360) {
        s.kind = n == 1 ? Kind::none : Kind::discrete_z;
        s.order = n;
        return s;
      }
    } catch (const std::exception&) {
    }
  }
  throw std::invalid_argument("symmetry '" + text + "': expected none, z:N (N-fold about z, 1..360) or z:inf");
}

std::string PartSymmetry::str() const {
  switch (kind) {
    case Kind::none:
      return "none";
    case Kind::discrete_z:
      return "z:" + std::to_string(order);
    case Kind::continuous_z:
      return "z:inf";
  }
  return "none";
}

std::vector<cv::Matx33d> PartSymmetry::discrete_rotations() const {
  std::vector<cv::Matx33d> out{cv::Matx33d::eye()};
  if (kind != Kind::discrete_z) return out;
  for (int k = 1; k < order; ++k) out.push_back(rotation_about_z(2 * CV_PI * k / order));
  return out;
}

bool PartSymmetry::includes(const PartSymmetry& other) const {
  if (other.kind == Kind::none || kind == Kind::continuous_z) return true;
  if (kind == Kind::discrete_z && other.kind == Kind::discrete_z) return order % other.order == 0;
  return false;
}

void save_template_database(const TemplateDatabase& db, const std::filesystem::path& file) {
  if (!db.symmetry.includes(db.views_symmetry)) throw std::invalid_argument(file.string() + ": " + unfolded_views(db));
  Writer w;
  w.str(db.part_name);
  w.put<int32_t>(db.obj_id);
  put_symmetry(w, db.symmetry);
  put_camera(w, db.camera);
  w.put<double>(db.distance_mm);
  for (int i = 0; i < 3; ++i) w.put<double>(db.center_mm[i]);
  w.put<double>(db.diameter_mm);
  w.put<int32_t>(db.sphere_samples);
  w.put<int32_t>(db.q);
  w.put<uint8_t>(db.oriented ? 1 : 0);
  w.str(db.mesh.name);
  w.put(static_cast<uint32_t>(db.mesh.vertices.size()));
  for (const auto& v : db.mesh.vertices) w.put(v[0]), w.put(v[1]), w.put(v[2]);
  w.put(static_cast<uint32_t>(db.mesh.triangles.size()));
  for (const auto& t : db.mesh.triangles) w.put(t[0]), w.put(t[1]), w.put(t[2]);
  w.put(static_cast<uint32_t>(db.views.size()));
  for (const auto& v : db.views) {
    w.put<int32_t>(v.index);
    for (int i = 0; i < 3; ++i) w.put<double>(v.view_direction[i]);
    for (int i = 0; i < 9; ++i) w.put<double>(v.R_m2c.val[i]);
    for (int i = 0; i < 3; ++i) w.put<double>(v.t_m2c_mm[i]);
    put_lines(w, v.lines);
    w.put(static_cast<uint32_t>(v.points.size()));
    for (const auto& p : v.points) {
      w.put(p.pixel.x), w.put(p.pixel.y), w.put(p.direction);
      w.put(p.model_mm[0]), w.put(p.model_mm[1]), w.put(p.model_mm[2]);
    }
    w.put(v.box.x), w.put(v.box.y), w.put(v.box.width), w.put(v.box.height);
  }
  for (const auto* profile : {&db.template_edge_offset, &db.query_edge_offset}) {
    w.put(static_cast<uint32_t>(profile->offset_px.size()));
    for (float o : profile->offset_px) w.put(o);
  }
  put_symmetry(w, db.views_symmetry);
  put_turns(w, db.turns);

  Writer h;
  for (char c : kMagic) h.put(c);
  h.put<uint32_t>(TemplateDatabase::kVersion);
  h.put<uint32_t>(kHeaderBytes);
  h.put<uint64_t>(w.bytes.size());
  h.put<uint32_t>(crc_of(w.bytes.data(), w.bytes.size()));
  h.put<uint32_t>(0);

  // Written next to the target and renamed, so a reader never sees half a file.
  const std::filesystem::path tmp = file.string() + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error(tmp.string() + ": cannot create");
    out.write(reinterpret_cast<const char*>(h.bytes.data()), static_cast<std::streamsize>(h.bytes.size()));
    out.write(reinterpret_cast<const char*>(w.bytes.data()), static_cast<std::streamsize>(w.bytes.size()));
    out.flush();
    if (!out) throw std::runtime_error(tmp.string() + ": write failed");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, file, ec);
  if (ec) throw std::runtime_error(file.string() + ": cannot rename from " + tmp.string() + ": " + ec.message());
}

TemplateDatabase load_template_database(const std::filesystem::path& file) {
  const std::string src = file.string();
  const std::vector<uint8_t> bytes = read_all(file);
  if (bytes.size() < kHeaderBytes) {
    if (bytes.size() >= sizeof(kMagic) && std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) == 0)
      throw TemplateFileError(src + ": truncated: " + std::to_string(bytes.size()) + " bytes, the header alone is " +
                              std::to_string(kHeaderBytes));
    throw TemplateFileError(src + ": not a template database (file too short for the header)");
  }
  if (std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0)
    throw TemplateFileError(src + ": not a template database (bad magic; expected a file written by mfc-teach)");
  Reader hr(bytes.data(), kHeaderBytes, src);
  for (size_t i = 0; i < sizeof(kMagic); ++i) hr.get<char>("magic");
  const auto version = hr.get<uint32_t>("version");
  const auto header_bytes = hr.get<uint32_t>("header size");
  const auto payload_bytes = hr.get<uint64_t>("payload size");
  const auto crc = hr.get<uint32_t>("checksum");
  if (version < TemplateDatabase::kOldestVersion || version > TemplateDatabase::kVersion)
    throw TemplateFileError(src + ": template database version " + std::to_string(version) +
                            ", this build reads versions " + std::to_string(TemplateDatabase::kOldestVersion) + " to " +
                            std::to_string(TemplateDatabase::kVersion) +
                            " (re-run mfc-teach: version 6 stores the part's turns, docs/template-database.md)");
  if (header_bytes != kHeaderBytes)
    throw TemplateFileError(src + ": header size " + std::to_string(header_bytes) + ", expected " +
                            std::to_string(kHeaderBytes));
  const uint64_t have = bytes.size() - kHeaderBytes;
  if (have < payload_bytes)
    throw TemplateFileError(src + ": truncated: payload has " + std::to_string(have) + " of " +
                            std::to_string(payload_bytes) + " bytes");
  if (have > payload_bytes)
    throw TemplateFileError(src + ": " + std::to_string(have - payload_bytes) + " unexpected bytes after the payload");
  const uint8_t* payload = bytes.data() + kHeaderBytes;
  const uint32_t actual = crc_of(payload, payload_bytes);
  if (actual != crc) {
    char msg[96];
    std::snprintf(msg, sizeof msg, ": checksum mismatch (header CRC-32 %08x, payload %08x): the file is corrupt", crc,
                  actual);
    throw TemplateFileError(src + msg);
  }

  Reader r(payload, payload_bytes, src);
  TemplateDatabase db;
  db.part_name = r.str("part name");
  db.obj_id = r.get<int32_t>("obj_id");
  db.symmetry = get_symmetry(r, "symmetry");
  db.camera = get_camera(r);
  db.distance_mm = r.finite("distance");
  for (int i = 0; i < 3; ++i) db.center_mm[i] = r.finite("centre");
  db.diameter_mm = r.finite("diameter");
  db.sphere_samples = r.get<int32_t>("sphere samples");
  db.q = r.get<int32_t>("q");
  if (db.q < 1 || db.q > kMaxChannels) r.fail("q = " + std::to_string(db.q) + " out of range");
  const auto oriented = r.get<uint8_t>("oriented");
  if (oriented > 1) r.fail("oriented flag " + std::to_string(oriented) + " is neither 0 nor 1");
  db.oriented = oriented == 1;
  if (db.oriented && db.q % 2 != 0) r.fail("oriented lines with an odd q = " + std::to_string(db.q));
  db.mesh.name = r.str("mesh name");
  db.mesh.vertices.resize(r.count("vertex count", 12));
  for (auto& v : db.mesh.vertices)
    for (int i = 0; i < 3; ++i) v[i] = r.get<float>("vertex");
  db.mesh.triangles.resize(r.count("triangle count", 12));
  for (auto& t : db.mesh.triangles)
    for (int i = 0; i < 3; ++i) {
      t[i] = r.get<uint32_t>("triangle");
      if (t[i] >= db.mesh.vertices.size()) r.fail("triangle index " + std::to_string(t[i]) + " out of range");
    }
  db.views.resize(r.count("view count", 200));
  for (auto& v : db.views) {
    v.index = r.get<int32_t>("view index");
    for (int i = 0; i < 3; ++i) v.view_direction[i] = r.finite("view direction");
    for (int i = 0; i < 9; ++i) v.R_m2c.val[i] = r.finite("view rotation");
    for (int i = 0; i < 3; ++i) v.t_m2c_mm[i] = r.finite("view translation");
    v.lines = get_lines(r, db.q, db.oriented);
    v.points.resize(r.count("edge point count", 24));
    for (auto& p : v.points) {
      p.pixel.x = r.get<float>("edge point"), p.pixel.y = r.get<float>("edge point");
      p.direction = r.get<float>("edge point");
      for (int i = 0; i < 3; ++i) p.model_mm[i] = r.get<float>("edge point");
    }
    v.box.x = r.get<float>("box"), v.box.y = r.get<float>("box");
    v.box.width = r.get<float>("box"), v.box.height = r.get<float>("box");
  }
  for (auto* profile : {&db.template_edge_offset, &db.query_edge_offset}) {
    const uint32_t n = r.count("edge offset profile size", 4);
    if (n != 0 && n != EdgeOffsetProfile::kBins)
      r.fail("edge offset profile of " + std::to_string(n) + " bins, expected 0 or " +
             std::to_string(EdgeOffsetProfile::kBins));
    profile->offset_px.resize(n);
    for (float& o : profile->offset_px) {
      o = r.get<float>("edge offset");
      // A detected edge pixel lies within a few pixels of the outline; anything else is corruption.
      if (!std::isfinite(o) || std::abs(o) > 3) r.fail("edge offset " + std::to_string(o) + " px out of range");
    }
  }
  db.views_symmetry = get_symmetry(r, "views symmetry");
  if (!db.symmetry.includes(db.views_symmetry)) r.fail(unfolded_views(db));
  db.turns = get_turns(r);
  if (r.remaining() != 0) r.fail(std::to_string(r.remaining()) + " bytes left after the part's turns");
  return db;
}

void check_template_camera(const TemplateDatabase& db, const CameraConfig& camera, const std::string& source) {
  const auto& a = db.camera.camera;
  const auto& b = camera.camera;
  std::ostringstream why;
  if (a.image_size != b.image_size)
    why << "image size " << a.image_size.width << "x" << a.image_size.height << " vs " << b.image_size.width << "x"
        << b.image_size.height;
  else {
    const char* names[] = {"fx", "skew", "cx", "", "fy", "cy"};
    const int idx[] = {0, 1, 2, 4, 5};
    for (int i : idx) {
      const double x = a.K.val[i], y = b.K.val[i];
      // Intrinsics within 0.1 % (0.5 px at f = 500 and above) render the same templates to a pixel.
      if (std::abs(x - y) > 1e-3 * std::max({1.0, std::abs(x), std::abs(y)})) {
        why << names[i] << " " << x << " vs " << y;
        break;
      }
    }
  }
  if (why.str().empty()) {
    const auto& fa = db.camera.flashes.positions_mm;
    const auto& fb = camera.flashes.positions_mm;
    if (fa.size() != fb.size())
      why << fa.size() << " flashes vs " << fb.size();
    else
      for (size_t i = 0; i < fa.size(); ++i)
        if (cv::norm(fa[i] - fb[i]) > 0.5) {
          why << "flash " << i << " at (" << fa[i][0] << ", " << fa[i][1] << ", " << fa[i][2] << ") mm vs (" << fb[i][0]
              << ", " << fb[i][1] << ", " << fb[i][2] << ") mm";
          break;
        }
  }
  if (!why.str().empty())
    throw TemplateFileError(source + ": built for another camera (" + why.str() +
                            "); re-run mfc-teach with this camera's YAML");
}

}  // namespace mfcd::vision
