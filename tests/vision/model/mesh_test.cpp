#include "vision/model/mesh.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>

using namespace mfcd::vision;
namespace fs = std::filesystem;

namespace {

fs::path temp_file(const std::string& name) {
  fs::path dir = fs::temp_directory_path() / ("mfcd-model-test-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir / name;
}

cv::Vec3f normal_of(const Mesh& m, const std::array<uint32_t, 3>& t) {
  return cv::normalize((m.vertices[t[1]] - m.vertices[t[0]]).cross(m.vertices[t[2]] - m.vertices[t[0]]));
}

// Minimal writers for the four formats, so the loader is tested on files we made.
void write_ascii_stl(const Mesh& m, const fs::path& p) {
  std::ofstream o(p);
  o << "solid test\n";
  for (const auto& t : m.triangles) {
    const cv::Vec3f n = normal_of(m, t);
    o << " facet normal " << n[0] << ' ' << n[1] << ' ' << n[2] << "\n  outer loop\n";
    for (uint32_t i : t)
      o << "   vertex " << m.vertices[i][0] << ' ' << m.vertices[i][1] << ' ' << m.vertices[i][2] << "\n";
    o << "  endloop\n endfacet\n";
  }
  o << "endsolid test\n";
}

void write_binary_stl(const Mesh& m, const fs::path& p) {
  std::ofstream o(p, std::ios::binary);
  char header[80] = "binary test part";
  o.write(header, 80);
  const auto n = static_cast<uint32_t>(m.triangles.size());
  o.write(reinterpret_cast<const char*>(&n), 4);
  for (const auto& t : m.triangles) {
    const cv::Vec3f nn = normal_of(m, t);
    o.write(reinterpret_cast<const char*>(&nn[0]), 12);
    for (uint32_t i : t) o.write(reinterpret_cast<const char*>(&m.vertices[i][0]), 12);
    const uint16_t attr = 0;
    o.write(reinterpret_cast<const char*>(&attr), 2);
  }
}

void write_obj(const Mesh& m, const fs::path& p) {
  std::ofstream o(p);
  for (const auto& v : m.vertices) o << "v " << v[0] << ' ' << v[1] << ' ' << v[2] << "\n";
  for (const auto& t : m.triangles) o << "f " << t[0] + 1 << ' ' << t[1] + 1 << ' ' << t[2] + 1 << "\n";
}

void write_ply(const Mesh& m, const fs::path& p) {
  std::ofstream o(p);
  o << "ply\nformat ascii 1.0\nelement vertex " << m.vertices.size()
    << "\nproperty float x\nproperty float y\nproperty float z\nelement face " << m.triangles.size()
    << "\nproperty list uchar int vertex_indices\nend_header\n";
  for (const auto& v : m.vertices) o << v[0] << ' ' << v[1] << ' ' << v[2] << "\n";
  for (const auto& t : m.triangles) o << "3 " << t[0] << ' ' << t[1] << ' ' << t[2] << "\n";
}

// Signed volume by the divergence theorem: positive for outward-oriented closed meshes.
double signed_volume(const Mesh& m) {
  double v = 0;
  for (const auto& t : m.triangles)
    v += static_cast<double>(m.vertices[t[0]].dot(m.vertices[t[1]].cross(m.vertices[t[2]]))) / 6.0;
  return v;
}

std::string load_error(const fs::path& p, const MeshLoadOptions& o = {}) {
  try {
    load_mesh(p, o);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(MeshShapes, GeneratedShapesAreClosedOutwardAndOfTheRightVolume) {
  const double pi = std::numbers::pi;
  struct Case {
    Mesh mesh;
    double volume, tolerance;
  };
  const std::vector<Case> cases = {
      {make_box(40, 30, 20), 40.0 * 30 * 20, 1e-6},
      {make_uv_sphere(20, 128, 64), 4.0 / 3 * pi * 8000, 0.005},
      {make_cylinder(15, 30, 128), pi * 225 * 30, 0.005},
  };
  for (const auto& c : cases) {
    const MeshReport r = validate_mesh(c.mesh, {}, c.mesh.name);
    EXPECT_EQ(r.open_edges, 0u) << c.mesh.name;
    EXPECT_EQ(r.non_manifold_edges, 0u) << c.mesh.name;
    EXPECT_EQ(r.degenerate_triangles, 0u) << c.mesh.name;
    EXPECT_NEAR(signed_volume(c.mesh) / c.volume, 1.0, c.tolerance) << c.mesh.name;
  }
  const Mesh plane = make_plane(100);
  EXPECT_LT(normal_of(plane, plane.triangles[0])[2], -0.99f);  // faces a camera looking along +z
}

TEST(MeshLoad, AllFormatsGiveTheSameBox) {
  const Mesh box = make_box(40, 30, 20);
  using Writer = void (*)(const Mesh&, const fs::path&);
  const std::vector<std::pair<std::string, Writer>> formats = {{"box_ascii.stl", write_ascii_stl},
                                                               {"box_binary.stl", write_binary_stl},
                                                               {"box.obj", write_obj},
                                                               {"box.ply", write_ply}};
  for (const auto& [name, write] : formats) {
    const fs::path p = temp_file(name);
    write(box, p);
    MeshReport report;
    const Mesh m = load_mesh(p, {}, &report);
    EXPECT_EQ(m.triangles.size(), 12u) << name;
    EXPECT_EQ(m.vertices.size(), 8u) << name << ": identical vertices must be joined";
    EXPECT_EQ(report.open_edges, 0u) << name;
    EXPECT_TRUE(report.warnings.empty()) << name;
    EXPECT_NEAR(signed_volume(m), 24000.0, 1e-3) << name;
    EXPECT_EQ(m.bbox_min(), cv::Vec3f(-20, -15, -10)) << name;
    EXPECT_EQ(m.bbox_max(), cv::Vec3f(20, 15, 10)) << name;
  }
}

TEST(MeshLoad, UnitScalesToMillimetres) {
  const fs::path p = temp_file("inch_box.stl");
  write_binary_stl(make_box(2, 1, 1), p);
  MeshLoadOptions inches;
  inches.unit_mm = parse_unit_mm("in");
  const Mesh m = load_mesh(p, inches);
  EXPECT_NEAR(m.bbox_max()[0] - m.bbox_min()[0], 50.8, 1e-4);
  EXPECT_DOUBLE_EQ(parse_unit_mm("m"), 1000.0);
  EXPECT_DOUBLE_EQ(parse_unit_mm("2.5"), 2.5);
  EXPECT_THROW(parse_unit_mm("furlong"), std::runtime_error);
  EXPECT_THROW(parse_unit_mm("-3"), std::runtime_error);
}

TEST(MeshLoad, AbsurdSizeNamesFileAndSuggestsUnit) {
  const fs::path p = temp_file("metres.stl");
  write_binary_stl(make_box(0.04, 0.03, 0.02), p);  // a part exported in metres
  const std::string err = load_error(p);
  EXPECT_NE(err.find(p.string()), std::string::npos) << err;
  EXPECT_NE(err.find("unit"), std::string::npos) << err;
  MeshLoadOptions metres;
  metres.unit_mm = 1000;
  EXPECT_EQ(load_error(p, metres), "");
  const fs::path big = temp_file("huge.stl");
  write_binary_stl(make_box(40000, 10, 10), big);
  EXPECT_NE(load_error(big).find("outside"), std::string::npos);
}

TEST(MeshLoad, EmptyMissingAndGarbageFilesAreErrors) {
  const fs::path empty = temp_file("empty.stl");
  std::ofstream(empty) << "solid nothing\nendsolid nothing\n";
  EXPECT_NE(load_error(empty).find(empty.string()), std::string::npos);
  EXPECT_NE(load_error(temp_file("nope.stl")).find("no such file"), std::string::npos);
  const fs::path garbage = temp_file("garbage.ply");
  std::ofstream(garbage) << "this is not a mesh\n";
  EXPECT_NE(load_error(garbage).find(garbage.string()), std::string::npos);
}

// assimp would read an OFF (and some 40 other formats); only .stl, .obj and .ply are accepted.
TEST(MeshLoad, OnlyStlObjAndPlyExtensionsAreRead) {
  const fs::path off = temp_file("box.off");
  {
    const Mesh box = make_box(40, 30, 20);
    std::ofstream o(off);
    o << "OFF\n" << box.vertices.size() << ' ' << box.triangles.size() << " 0\n";
    for (const auto& v : box.vertices) o << v[0] << ' ' << v[1] << ' ' << v[2] << "\n";
    for (const auto& t : box.triangles) o << "3 " << t[0] << ' ' << t[1] << ' ' << t[2] << "\n";
  }
  const std::string err = load_error(off);
  EXPECT_NE(err.find(off.string()), std::string::npos) << err;
  EXPECT_NE(err.find(".stl, .obj, .ply"), std::string::npos) << err;
  fs::path bare = temp_file("box");
  write_obj(make_box(40, 30, 20), bare);
  EXPECT_NE(load_error(bare).find("unsupported mesh format"), std::string::npos) << load_error(bare);
  const fs::path upper = temp_file("box.OBJ");
  write_obj(make_box(40, 30, 20), upper);
  EXPECT_EQ(load_error(upper), "");
}

// A non-finite coordinate is refused before welding, where it would compare equal to a finite
// neighbour and vanish into it.
TEST(MeshLoad, NonFiniteVertexIsRefusedBeforeWelding) {
  Mesh m = make_box(10, 10, 10);
  m.vertices.emplace_back(std::numeric_limits<float>::quiet_NaN(), -5.f, -5.f);  // (-5, -5, -5) is vertex 0
  m.triangles.push_back({static_cast<uint32_t>(m.vertices.size() - 1), 1, 2});
  const fs::path p = temp_file("nan.ply");
  write_ply(m, p);
  const std::string err = load_error(p);
  EXPECT_NE(err.find("non-finite"), std::string::npos) << err;
  EXPECT_NE(err.find(p.string()), std::string::npos) << err;
}

TEST(MeshLoad, FaceIndexOutsideTheVerticesIsRefused) {
  Mesh m = make_box(10, 10, 10);
  m.triangles.push_back({0, 1, 8});
  for (const char* name : {"index.obj", "index.ply"}) {
    const fs::path p = temp_file(name);
    fs::path(name).extension() == ".obj" ? write_obj(m, p) : write_ply(m, p);
    const std::string err = load_error(p);
    EXPECT_NE(err.find(p.string()), std::string::npos) << err;
  }
}

TEST(MeshValidate, OpenAndNonManifoldEdgesWarnButLoad) {
  Mesh open = make_box(40, 30, 20);
  open.triangles.pop_back();
  const fs::path p = temp_file("open.obj");
  write_obj(open, p);
  MeshReport r;
  const Mesh m = load_mesh(p, {}, &r);
  EXPECT_EQ(m.triangles.size(), 11u);
  EXPECT_EQ(r.open_edges, 3u);
  ASSERT_FALSE(r.warnings.empty());
  EXPECT_NE(r.warnings[0].find("open edges"), std::string::npos);

  Mesh fin = make_box(40, 30, 20);  // a fin: a third triangle on the edge between vertices 0 and 1
  fin.vertices.emplace_back(0.f, -40.f, -10.f);
  fin.triangles.push_back({0, 1, static_cast<uint32_t>(fin.vertices.size() - 1)});
  const MeshReport rf = validate_mesh(fin);
  EXPECT_EQ(rf.non_manifold_edges, 1u);
  bool named = false;
  for (const auto& w : rf.warnings) named |= w.find("non-manifold") != std::string::npos;
  EXPECT_TRUE(named);

  Mesh bad = make_box(10, 10, 10);
  bad.triangles.push_back({0, 1, 99});
  EXPECT_THROW(validate_mesh(bad), std::runtime_error);
  EXPECT_THROW(validate_mesh(Mesh{}), std::runtime_error);
}
