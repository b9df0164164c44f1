// The PLY reader: the same box written as ASCII, binary little- and big-endian PLY (with the
// extras real files carry: comments, normals, colours, quads, other elements) reads back as the
// box itself, also through load_mesh; damaged files are refused with the file and the reason.
#include "vision/model/ply_reader.hpp"

#include <gtest/gtest.h>

#include <unistd.h>
#include <bit>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

using namespace mfcd::vision;
namespace fs = std::filesystem;

namespace {

fs::path temp_file(const std::string& name) {
  return fs::temp_directory_path() / ("mfcd_ply_" + std::to_string(::getpid()) + "_" + name);
}

// The box's 8 corners and its 6 sides as quads (outward), as a CAD exporter writes them.
const float kCorners[8][3] = {{-20, -15, -10}, {20, -15, -10}, {-20, 15, -10}, {20, 15, -10},
                              {-20, -15, 10},  {20, -15, 10},  {-20, 15, 10},  {20, 15, 10}};
const int kQuads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};

std::string header(const std::string& format, int vertices = 8, int faces = 6) {
  return "ply\nformat " + format + " 1.0\ncomment made by a test\nobj_info nothing\nelement vertex " +
         std::to_string(vertices) +
         "\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\n"
         "property float nz\nproperty uchar red\nproperty list uchar float texcoord\nelement face " +
         std::to_string(faces) +
         "\nproperty list uchar int vertex_indices\nproperty uchar flags\n"
         "element material 1\nproperty double shininess\nend_header\n";
}

template <class T>
void put(std::string& out, T v, bool big) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof v);
  if (big == (std::endian::native == std::endian::little)) std::reverse(b, b + sizeof v);
  out.append(b, sizeof v);
}

void write_binary(const fs::path& p, bool big) {
  std::string s = header(big ? "binary_big_endian" : "binary_little_endian");
  for (const auto& c : kCorners) {
    for (float v : c) put(s, v, big);
    for (float n : {0.f, 0.f, 1.f}) put(s, n, big);
    put<uint8_t>(s, 200, big);
    put<uint8_t>(s, 2, big);
    put(s, 0.25f, big), put(s, 0.75f, big);
  }
  for (const auto& q : kQuads) {
    put<uint8_t>(s, 4, big);
    for (int i : q) put<int32_t>(s, i, big);
    put<uint8_t>(s, 7, big);
  }
  put(s, 0.5, big);
  std::ofstream(p, std::ios::binary) << s;
}

void write_ascii(const fs::path& p) {
  std::ofstream o(p);
  o << header("ascii");
  for (const auto& c : kCorners) o << c[0] << ' ' << c[1] << ' ' << c[2] << " 0 0 1 200 2 0.25 0.75\n";
  for (const auto& q : kQuads) o << "4 " << q[0] << ' ' << q[1] << ' ' << q[2] << ' ' << q[3] << " 7\n";
  o << "0.5\n";
}

std::string refusal(const fs::path& p) {
  try {
    read_ply(p);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(PlyReader, AsciiAndBothBinaryByteOrdersGiveTheSameBox) {
  const fs::path a = temp_file("a.ply"), le = temp_file("le.ply"), be = temp_file("be.ply");
  write_ascii(a);
  write_binary(le, false);
  write_binary(be, true);
  const Mesh ref = read_ply(a);
  ASSERT_EQ(ref.vertices.size(), 8u);
  ASSERT_EQ(ref.triangles.size(), 12u);  // each quad fanned into two triangles
  for (int i = 0; i < 8; ++i) EXPECT_EQ(ref.vertices[i], cv::Vec3f(kCorners[i][0], kCorners[i][1], kCorners[i][2]));
  EXPECT_EQ(ref.triangles[0], (std::array<uint32_t, 3>{0, 2, 3}));
  EXPECT_EQ(ref.triangles[1], (std::array<uint32_t, 3>{0, 3, 1}));
  for (const fs::path& p : {le, be}) {
    const Mesh m = read_ply(p, 2.0f);
    ASSERT_EQ(m.vertices.size(), ref.vertices.size()) << p;
    for (size_t i = 0; i < m.vertices.size(); ++i) EXPECT_EQ(m.vertices[i], ref.vertices[i] * 2.0f) << p;
    EXPECT_EQ(m.triangles, ref.triangles) << p;
    // load_mesh reads binary PLY through this reader, validated and closed.
    MeshReport report;
    const Mesh loaded = load_mesh(p, {}, &report);
    EXPECT_EQ(loaded.triangles.size(), 12u);
    EXPECT_EQ(report.open_edges, 0u);
    EXPECT_TRUE(report.warnings.empty());
  }
  for (const fs::path& p : {a, le, be}) fs::remove(p);
}

TEST(PlyReader, DamagedFilesAreRefusedWithTheReason) {
  const fs::path p = temp_file("bad.ply");
  auto expect = [&](const std::string& body, const std::string& reason) {
    std::ofstream(p, std::ios::binary) << body;
    const std::string why = refusal(p);
    EXPECT_NE(why.find(p.string()), std::string::npos) << why;
    EXPECT_NE(why.find(reason), std::string::npos) << "wanted '" << reason << "' in: " << why;
  };
  expect("solid box\n", "not a PLY file");
  expect("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n", "no 'end_header'");
  expect("ply\nformat zip 1.0\nend_header\n", "unknown format 'zip'");
  expect("ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n", "unknown property type 'quad'");
  // A count the file cannot hold is refused before anything is allocated for it.
  expect(header("binary_little_endian", 2000000000, 6) + std::string(300, '\0'), "declares 2000000000 instances");
  std::string le = header("binary_little_endian");
  write_binary(p, false);
  std::ifstream in(p, std::ios::binary);
  const std::string whole((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  expect(whole.substr(0, whole.size() - 20), "truncated");
  // A face pointing past the vertices.
  std::string bad = whole;
  const size_t first_index = le.size() + 8 * (6 * 4 + 1 + 1 + 8) + 1;
  const int32_t huge = 99;
  std::memcpy(bad.data() + first_index, &huge, 4);
  expect(bad, "vertex index 99");
  const std::string xyz =
      "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
      "property float z\nend_header\n";
  expect(xyz + "1 2 3\n4 x 6\n", "line 9: expected a number");
  expect(xyz + "1 2 3\n4 5          \n", "truncated");
  expect("ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n", "no 'vertex'");
  fs::remove(p);
}
