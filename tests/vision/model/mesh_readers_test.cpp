// read_stl and read_obj on files written here, and against their slow twin: assimp's STL and OBJ
// importers (what load_mesh used before; kept as the tests' reference only), on the same files.
// The coordinates written have at most 9 significant digits, where assimp's own text-to-float
// conversion agrees with the correctly rounded std::from_chars the readers use; on longer ones
// (OpenSCAD writes 17) it can be one unit in the last place off.
#include "vision/model/obj_reader.hpp"
#include "vision/model/stl_reader.hpp"
#include "vision/model/text_tokens.hpp"

#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <assimp/Importer.hpp>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

using namespace mfcd::vision;
namespace fs = std::filesystem;

namespace {

fs::path temp_file(const std::string& name) {
  fs::path dir = fs::temp_directory_path() / ("mfcd-readers-test-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir / name;
}

using Triangle = std::array<cv::Vec3f, 3>;

// Every triangle as its corners, started at its smallest corner (the winding kept), sorted: what
// two readers must agree on whatever their vertex numbering.
std::vector<Triangle> corners_of(const Mesh& m) {
  auto less = [](const cv::Vec3f& a, const cv::Vec3f& b) {
    return std::lexicographical_compare(a.val, a.val + 3, b.val, b.val + 3);
  };
  std::vector<Triangle> out;
  for (const auto& t : m.triangles) {
    Triangle c{m.vertices.at(t[0]), m.vertices.at(t[1]), m.vertices.at(t[2])};
    const auto first = std::min_element(c.begin(), c.end(), less) - c.begin();
    std::rotate(c.begin(), c.begin() + first, c.end());
    out.push_back(c);
  }
  std::sort(out.begin(), out.end(), [&](const Triangle& a, const Triangle& b) {
    return std::lexicographical_compare(a.begin(), a.end(), b.begin(), b.end(), less);
  });
  return out;
}

// The slow twin: assimp's importer for the file's extension, its meshes' triangles.
Mesh read_with_assimp(const fs::path& file) {
  Assimp::Importer importer;
  const aiScene* scene =
      importer.ReadFile(file.string(), aiProcess_ValidateDataStructure | aiProcess_Triangulate | aiProcess_SortByPType);
  if (!scene) throw std::runtime_error(importer.GetErrorString());
  Mesh m;
  for (unsigned i = 0; i < scene->mNumMeshes; ++i) {
    const aiMesh* am = scene->mMeshes[i];
    const auto base = static_cast<uint32_t>(m.vertices.size());
    for (unsigned v = 0; v < am->mNumVertices; ++v)
      m.vertices.emplace_back(am->mVertices[v].x, am->mVertices[v].y, am->mVertices[v].z);
    for (unsigned f = 0; f < am->mNumFaces; ++f)
      if (am->mFaces[f].mNumIndices == 3)
        m.triangles.push_back(
            {base + am->mFaces[f].mIndices[0], base + am->mFaces[f].mIndices[1], base + am->mFaces[f].mIndices[2]});
  }
  return m;
}

// A random closed-ish triangle soup with coordinates of a few decimals (exact in text and float).
Mesh random_mesh(std::mt19937& rng, int vertices, int triangles) {
  std::uniform_int_distribution<int> c(-50000, 50000), pick(0, vertices - 1);
  Mesh m;
  for (int i = 0; i < vertices; ++i) m.vertices.emplace_back(c(rng) / 1000.f, c(rng) / 1000.f, c(rng) / 1000.f);
  while (static_cast<int>(m.triangles.size()) < triangles) {
    const auto a = static_cast<uint32_t>(pick(rng)), b = static_cast<uint32_t>(pick(rng)),
               d = static_cast<uint32_t>(pick(rng));
    if (a != b && b != d && a != d) m.triangles.push_back({a, b, d});
  }
  return m;
}

std::string text(const cv::Vec3f& v) {
  std::ostringstream s;
  s.precision(9);
  s << v[0] << ' ' << v[1] << ' ' << v[2];
  return s.str();
}

void write_ascii_stl(const Mesh& m, const fs::path& p, bool two_solids = false) {
  std::ofstream o(p, std::ios::binary);
  o << "solid first\r\n";
  for (size_t i = 0; i < m.triangles.size(); ++i) {
    if (two_solids && i == m.triangles.size() / 2) o << "endsolid first\nsolid second\n";
    o << "  facet normal 0 0 1\n    outer loop\n";
    for (uint32_t k : m.triangles[i]) o << "\tvertex   " << text(m.vertices[k]) << "\n";
    o << "    endloop\n  endfacet\n";
  }
  o << "endsolid\n";
}

void write_binary_stl(const Mesh& m, const fs::path& p, const char* header) {
  std::ofstream o(p, std::ios::binary);
  char h[80] = {};
  std::strncpy(h, header, sizeof h - 1);
  o.write(h, 80);
  const auto n = static_cast<uint32_t>(m.triangles.size());
  o.write(reinterpret_cast<const char*>(&n), 4);
  for (const auto& t : m.triangles) {
    const float normal[3] = {0, 0, 1};
    o.write(reinterpret_cast<const char*>(normal), 12);
    for (uint32_t i : t) o.write(reinterpret_cast<const char*>(&m.vertices[i][0]), 12);
    const uint16_t attr = 0;
    o.write(reinterpret_cast<const char*>(&attr), 2);
  }
}

// Corners written in every form OBJ has, negative (relative) indices for some faces, groups,
// normals, texture coordinates, CR LF line ends and comment lines between (assimp refuses a
// comment after a face on its line; read_obj reads past it, ScaleAndPolygons).
void write_obj(const Mesh& m, const fs::path& p) {
  std::ofstream o(p, std::ios::binary);
  o << "# written by the test\nmtllib parts.mtl\no part\n";
  for (const auto& v : m.vertices) o << "v " << text(v) << "\n";
  o << "vt 0.5 0.5\nvn 0 0 1\ng side\nusemtl steel\ns 1\n";
  const int n = static_cast<int>(m.vertices.size());
  for (size_t i = 0; i < m.triangles.size(); ++i) {
    const auto& t = m.triangles[i];
    o << "f";
    for (uint32_t k : t) {
      switch (i % 5) {
        case 0:
          o << ' ' << k + 1;
          break;
        case 1:
          o << ' ' << k + 1 << "/1";
          break;
        case 2:
          o << ' ' << k + 1 << "//1";
          break;
        case 3:
          o << ' ' << k + 1 << "/1/1";
          break;
        default:
          o << ' ' << static_cast<int>(k) - n;
          break;
      }
    }
    o << (i % 7 == 0 ? "\r\n# a comment line\n" : "\n");
  }
}

std::string error_of(Mesh (*read)(const fs::path&, float), const fs::path& p) {
  try {
    read(p, 1.0f);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(MeshReaders, StlAndObjGiveWhatAssimpGives) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 4; ++trial) {
    const Mesh m = random_mesh(rng, 40 + 30 * trial, 60 + 50 * trial);
    const auto want = corners_of(m);
    const fs::path ascii = temp_file("ascii.stl"), binary = temp_file("binary.stl"), solid = temp_file("solid.stl"),
                   obj = temp_file("part.obj");
    write_ascii_stl(m, ascii, trial % 2 == 1);
    write_binary_stl(m, binary, "binary part");
    write_binary_stl(m, solid, "solid part exported by a CAD tool that writes binary");
    write_obj(m, obj);
    for (const fs::path& p : {ascii, binary, solid}) {
      EXPECT_EQ(corners_of(read_stl(p)), want) << p << " trial " << trial;
      if (p != solid) {
        EXPECT_EQ(corners_of(read_with_assimp(p)), want) << p << " (assimp) trial " << trial;
      }
    }
    EXPECT_EQ(corners_of(read_obj(obj)), want) << "trial " << trial;
    EXPECT_EQ(corners_of(read_with_assimp(obj)), want) << "(assimp) trial " << trial;
  }
}

TEST(MeshReaders, ScaleAndPolygons) {
  const fs::path p = temp_file("quad.obj");
  std::ofstream(p) << "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 1.5 0 # the apex\nf 1 2 3 5 4 # a pentagon\n";
  const Mesh m = read_obj(p, 10.0f);
  ASSERT_EQ(m.triangles.size(), 3u);  // a pentagon, fanned from its first corner
  EXPECT_EQ(m.vertices[1], cv::Vec3f(10, 0, 0));
  for (const auto& t : m.triangles) EXPECT_EQ(t[0], 0u);
  EXPECT_EQ(m.name, "quad");
  Mesh tri;
  tri.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  tri.triangles = {{0, 1, 2}};
  const fs::path s = temp_file("one.stl");
  write_binary_stl(tri, s, "x");
  EXPECT_EQ(read_stl(s, 25.4f).vertices[1], cv::Vec3f(25.4f, 0, 0));
}

TEST(MeshReaders, MalformedFilesAreRefusedNamingFileAndLine) {
  auto refused = [](Mesh (*read)(const fs::path&, float), const std::string& name, const std::string& body,
                    const std::string& fragment) {
    const fs::path p = temp_file(name);
    std::ofstream(p, std::ios::binary) << body;
    const std::string err = error_of(read, p);
    EXPECT_NE(err.find(p.string()), std::string::npos) << name << ": " << err;
    EXPECT_NE(err.find(fragment), std::string::npos) << name << ": " << err;
  };
  const std::string facet =
      "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n";
  refused(read_stl, "a.stl", "not a mesh at all", "not an STL file");
  refused(read_stl, "b.stl", "solid x\n" + facet + "facet\nouter loop\nvertex 0 zero 0\n",
          ":11: 'zero' is not a finite number");
  refused(read_stl, "c.stl", "solid x\n" + facet, "unexpected end of file");
  refused(read_stl, "d.stl", "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nendloop\n",
          ":5: expected 'vertex', found 'endloop'");
  refused(read_stl, "e.stl", "solid x\nvertex 1 2 3\n", ":2: expected 'facet' or 'endsolid', found 'vertex'");
  refused(read_stl, "f.stl", "solid x\n" + facet + "endsolid\ngarbage\n", "expected 'solid', found 'garbage'");
  refused(read_stl, "g.stl", "solid x\nfacet normal 0 0 1\nouter loop\nvertex nan 0 0\n",
          "'nan' is not a finite number");
  {  // binary, one triangle short of its count: neither binary nor ASCII
    std::string bytes(84 + 50, '\0');
    bytes[80] = 2;
    refused(read_stl, "h.stl", bytes, "not an STL file");
  }
  refused(read_obj, "a.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", ":4: vertex index 0");
  refused(read_obj, "b.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n", ":3: a face needs at least three corners");
  refused(read_obj, "c.obj", "v 0 0 0\nv 1 0 x\n", ":2: 'x' is not a finite number");
  refused(read_obj, "d.obj", "v 0 0\n", ":1: a vertex needs x, y and z");
  refused(read_obj, "e.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n", ":4: vertex index -4 is before the first vertex");
  refused(read_obj, "f.obj", "v 0 0 0\n\nf 1 a 3\n", ":3: face corner 'a' has no vertex index");
  refused(read_obj, "g.obj", "v 0 0 0\nf 1 2 99999999999\n", "past 2^32");
  // A face may name a vertex defined later; whether it exists is load_mesh's question.
  const fs::path later = temp_file("later.obj");
  std::ofstream(later) << "f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n";
  EXPECT_EQ(read_obj(later).triangles.size(), 1u);
}

TEST(TextTokens, FloatsAreFiniteWholeWords) {
  float v = 0;
  EXPECT_TRUE(TextTokens::parse_float("1.5e2", v));
  EXPECT_EQ(v, 150.f);
  EXPECT_TRUE(TextTokens::parse_float("+2", v));
  EXPECT_EQ(v, 2.f);
  EXPECT_TRUE(TextTokens::parse_float("-0.25", v));
  for (const char* bad : {"", "1.5x", "inf", "nan", "1e99", "--1", "0x10", " 1"})
    EXPECT_FALSE(TextTokens::parse_float(bad, v)) << bad;
}
