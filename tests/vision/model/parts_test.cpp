// The six development parts built from config/parts/*.scad by the vision_parts_build
// fixture: each loads, is closed and manifold, and is 30-80 mm in size.
#include "vision/model/mesh.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

using namespace mfcd::vision;

class DevelopmentPart : public testing::TestWithParam<const char*> {};

TEST_P(DevelopmentPart, LoadsClosedAndSized) {
  const std::filesystem::path stl =
      std::filesystem::path(MFC_BINARY_DIR) / "parts" / (std::string(GetParam()) + ".stl");
  ASSERT_TRUE(std::filesystem::exists(stl)) << stl << " (built by the vision_parts_build test)";
  MeshReport report;
  const Mesh m = load_mesh(stl, {}, &report);
  EXPECT_GT(m.triangles.size(), 50u);
  EXPECT_EQ(report.open_edges, 0u);
  EXPECT_EQ(report.non_manifold_edges, 0u);
  const cv::Vec3f size = m.bbox_max() - m.bbox_min();
  const float largest = std::max({size[0], size[1], size[2]});
  EXPECT_GE(largest, 30.f);
  EXPECT_LE(largest, 80.f);
}

INSTANTIATE_TEST_SUITE_P(Parts, DevelopmentPart,
                         testing::Values("breaker", "diamond", "ellipse", "tnut", "knob", "wheel"));
