#include "vision/model/mesh.hpp"
#include "vision/model/obj_reader.hpp"
#include "vision/model/ply_reader.hpp"
#include "vision/model/stl_reader.hpp"

#include <syslog.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <stdexcept>

namespace mfcd::vision {

cv::Vec3f Mesh::bbox_min() const {
  cv::Vec3f m(std::numeric_limits<float>::max(), std::numeric_limits<float>::max(), std::numeric_limits<float>::max());
  for (const auto& v : vertices)
    for (int k = 0; k < 3; ++k) m[k] = std::min(m[k], v[k]);
  return m;
}

cv::Vec3f Mesh::bbox_max() const {
  cv::Vec3f m(std::numeric_limits<float>::lowest(), std::numeric_limits<float>::lowest(),
              std::numeric_limits<float>::lowest());
  for (const auto& v : vertices)
    for (int k = 0; k < 3; ++k) m[k] = std::max(m[k], v[k]);
  return m;
}

double parse_unit_mm(const std::string& unit) {
  if (unit == "mm") return 1.0;
  if (unit == "cm") return 10.0;
  if (unit == "m") return 1000.0;
  if (unit == "in" || unit == "inch") return 25.4;
  try {
    size_t used = 0;
    const double v = std::stod(unit, &used);
    if (used == unit.size() && v > 0 && std::isfinite(v)) return v;
  } catch (const std::exception&) {
  }
  throw std::runtime_error("unit '" + unit + "': expected mm, cm, m, in or a positive number of mm per unit");
}

namespace {

// STL stores each triangle's corners separately, and an OBJ may repeat a position under two
// indices, so connectivity is rebuilt from exactly equal positions.
void weld_identical_vertices(Mesh& mesh) {
  std::map<std::array<float, 3>, uint32_t> index;
  std::vector<cv::Vec3f> unique;
  std::vector<uint32_t> remap(mesh.vertices.size());
  for (size_t i = 0; i < mesh.vertices.size(); ++i) {
    const cv::Vec3f& v = mesh.vertices[i];
    const auto [it, inserted] = index.try_emplace({v[0], v[1], v[2]}, static_cast<uint32_t>(unique.size()));
    if (inserted) unique.push_back(v);
    remap[i] = it->second;
  }
  for (auto& t : mesh.triangles)
    for (auto& i : t) i = remap[i];
  mesh.vertices = std::move(unique);
}

// What welding, the topology count and every later stage index by: each triangle's corners name
// a vertex, and every vertex is finite (a NaN would break the weld's ordering and vanish into
// a neighbour). Checked before anything reads vertices through a triangle.
void check_indices_and_coordinates(const Mesh& mesh, const std::string& source) {
  if (mesh.vertices.empty() || mesh.triangles.empty()) throw std::runtime_error(source + ": empty mesh (no triangles)");
  for (const auto& v : mesh.vertices)
    if (!std::isfinite(v[0]) || !std::isfinite(v[1]) || !std::isfinite(v[2]))
      throw std::runtime_error(source + ": non-finite vertex coordinate");
  for (const auto& t : mesh.triangles)
    for (uint32_t i : t)
      if (i >= mesh.vertices.size())
        throw std::runtime_error(source + ": triangle index " + std::to_string(i) + " out of range (" +
                                 std::to_string(mesh.vertices.size()) + " vertices)");
}

}  // namespace

MeshReport validate_mesh(const Mesh& mesh, const MeshLoadOptions& options, const std::string& source) {
  check_indices_and_coordinates(mesh, source);
  MeshReport r;
  std::map<std::pair<uint32_t, uint32_t>, int> edge_use;
  for (const auto& t : mesh.triangles) {
    const cv::Vec3f e1 = mesh.vertices[t[1]] - mesh.vertices[t[0]];
    const cv::Vec3f e2 = mesh.vertices[t[2]] - mesh.vertices[t[0]];
    if (cv::norm(e1.cross(e2)) < 1e-12) ++r.degenerate_triangles;
    for (int k = 0; k < 3; ++k) {
      uint32_t a = t[static_cast<size_t>(k)], b = t[static_cast<size_t>((k + 1) % 3)];
      ++edge_use[{std::min(a, b), std::max(a, b)}];
    }
  }
  for (const auto& [edge, n] : edge_use) {
    if (n == 1) ++r.open_edges;
    if (n > 2) ++r.non_manifold_edges;
  }
  const cv::Vec3f size = mesh.bbox_max() - mesh.bbox_min();
  const double largest = std::max({size[0], size[1], size[2]});
  if (largest < options.min_size_mm || largest > options.max_size_mm)
    throw std::runtime_error(source + ": part size " + std::to_string(largest) + " mm is outside [" +
                             std::to_string(options.min_size_mm) + ", " + std::to_string(options.max_size_mm) +
                             "] mm; wrong unit? (unit_mm = " + std::to_string(options.unit_mm) + ")");
  if (r.open_edges) r.warnings.push_back(source + ": not closed: " + std::to_string(r.open_edges) + " open edges");
  if (r.non_manifold_edges)
    r.warnings.push_back(source + ": non-manifold: " + std::to_string(r.non_manifold_edges) +
                         " edges shared by more than two triangles");
  if (r.degenerate_triangles)
    r.warnings.push_back(source + ": " + std::to_string(r.degenerate_triangles) + " degenerate triangles");
  return r;
}

// What every format's loader ends with: shared vertices welded, the mesh validated, findings
// reported (to `report`, else syslog).
Mesh finish_loading(Mesh mesh, const MeshLoadOptions& options, MeshReport* report, const std::string& src) {
  check_indices_and_coordinates(mesh, src);
  weld_identical_vertices(mesh);
  MeshReport r = validate_mesh(mesh, options, src);
  for (const auto& w : r.warnings)
    if (!report) syslog(LOG_WARNING, "%s", w.c_str());
  if (report) *report = std::move(r);
  return mesh;
}

Mesh load_mesh(const std::filesystem::path& file, const MeshLoadOptions& options, MeshReport* report) {
  const std::string src = file.string();
  if (!(options.unit_mm > 0) || !std::isfinite(options.unit_mm))
    throw std::runtime_error(src + ": unit_mm must be a positive number");
  if (!std::filesystem::exists(file)) throw std::runtime_error(src + ": no such file");
  std::string ext = file.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  const auto scale = static_cast<float>(options.unit_mm);
  if (ext == ".ply") return finish_loading(read_ply(file, scale), options, report, src);
  if (ext == ".stl") return finish_loading(read_stl(file, scale), options, report, src);
  if (ext == ".obj") return finish_loading(read_obj(file, scale), options, report, src);
  if (ext == ".step" || ext == ".stp" || ext == ".iges" || ext == ".igs")
    throw std::runtime_error(src +
                             ": STEP and IGES parts are read by load_part (vision/model/cad_reader.hpp, OCCT), "
                             "as mfc-teach does");
  throw std::runtime_error(src + ": unsupported mesh format '" + ext +
                           "'; accepted: .stl, .obj, .ply, .step, .stp, .iges, .igs");
}

Mesh make_box(double sx, double sy, double sz) {
  Mesh m;
  m.name = "box";
  const float x = static_cast<float>(sx / 2), y = static_cast<float>(sy / 2), z = static_cast<float>(sz / 2);
  for (int i = 0; i < 8; ++i) m.vertices.emplace_back((i & 1) ? x : -x, (i & 2) ? y : -y, (i & 4) ? z : -z);
  // Counter-clockwise seen from outside (right-handed frame).
  m.triangles = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                 {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  return m;
}

Mesh make_uv_sphere(double radius, int slices, int stacks) {
  Mesh m;
  m.name = "sphere";
  const auto r = static_cast<float>(radius);
  m.vertices.emplace_back(0.f, 0.f, r);  // north pole
  for (int i = 1; i < stacks; ++i) {
    const double th = std::numbers::pi * i / stacks;
    for (int j = 0; j < slices; ++j) {
      const double ph = 2 * std::numbers::pi * j / slices;
      m.vertices.emplace_back(static_cast<float>(radius * std::sin(th) * std::cos(ph)),
                              static_cast<float>(radius * std::sin(th) * std::sin(ph)),
                              static_cast<float>(radius * std::cos(th)));
    }
  }
  m.vertices.emplace_back(0.f, 0.f, -r);  // south pole
  const auto S = static_cast<uint32_t>(slices);
  auto ring = [&](int i, int j) { return 1 + static_cast<uint32_t>(i - 1) * S + static_cast<uint32_t>(j % slices); };
  const auto south = static_cast<uint32_t>(m.vertices.size() - 1);
  for (int j = 0; j < slices; ++j) {
    m.triangles.push_back({0, ring(1, j), ring(1, j + 1)});
    for (int i = 1; i < stacks - 1; ++i) {
      m.triangles.push_back({ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)});
      m.triangles.push_back({ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)});
    }
    m.triangles.push_back({ring(stacks - 1, j), south, ring(stacks - 1, j + 1)});
  }
  return m;
}

Mesh make_cylinder(double radius, double height, int slices) {
  Mesh m;
  m.name = "cylinder";
  const auto h = static_cast<float>(height / 2);
  for (int j = 0; j < slices; ++j) {
    const double ph = 2 * std::numbers::pi * j / slices;
    const auto x = static_cast<float>(radius * std::cos(ph)), y = static_cast<float>(radius * std::sin(ph));
    m.vertices.emplace_back(x, y, -h);
    m.vertices.emplace_back(x, y, h);
  }
  const auto S = static_cast<uint32_t>(slices);
  const uint32_t bottom = 2 * S, top = 2 * S + 1;
  m.vertices.emplace_back(0.f, 0.f, -h);
  m.vertices.emplace_back(0.f, 0.f, h);
  for (uint32_t j = 0; j < S; ++j) {
    const uint32_t b0 = 2 * j, t0 = 2 * j + 1, b1 = 2 * ((j + 1) % S), t1 = b1 + 1;
    m.triangles.push_back({b0, b1, t1});
    m.triangles.push_back({b0, t1, t0});
    m.triangles.push_back({bottom, b1, b0});
    m.triangles.push_back({top, t0, t1});
  }
  return m;
}

Mesh make_plane(double size) {
  Mesh m;
  m.name = "plane";
  const auto s = static_cast<float>(size / 2);
  m.vertices = {{-s, -s, 0}, {s, -s, 0}, {s, s, 0}, {-s, s, 0}};
  // Seen from -z (the camera side) these run counter-clockwise, so the normal is -z.
  m.triangles = {{0, 2, 1}, {0, 3, 2}};
  return m;
}

}  // namespace mfcd::vision
