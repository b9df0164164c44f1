// The turns a part's edges may not tell apart, found from meshes made in code, each also placed
// in the model frame by an arbitrary rotation (a CAD file's axes are not the part's).
#include "vision/model/mesh_turns.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace mfcd::vision {
namespace {

constexpr double kPi = std::numbers::pi;

// `part` with `other` added, `other` moved by R and t first.
void add(Mesh& part, const Mesh& other, const cv::Matx33d& R = cv::Matx33d::eye(), const cv::Vec3d& t = {0, 0, 0}) {
  const auto base = static_cast<uint32_t>(part.vertices.size());
  for (const cv::Vec3f& v : other.vertices) {
    const cv::Vec3d p = R * cv::Vec3d(v[0], v[1], v[2]) + t;
    part.vertices.emplace_back(float(p[0]), float(p[1]), float(p[2]));
  }
  for (const auto& tri : other.triangles) part.triangles.push_back({tri[0] + base, tri[1] + base, tri[2] + base});
}

Mesh moved(const Mesh& m, const cv::Matx33d& R, const cv::Vec3d& t) {
  Mesh out;
  add(out, m, R, t);
  return out;
}

// An arbitrary model frame: the part's own axes are none of x, y, z.
const cv::Matx33d kFrame = axis_rotation(cv::normalize(cv::Vec3d(0.3, -0.5, 0.8)), 0.9);
const cv::Vec3d kShift(12, -7, 30);

double axis_deg(const cv::Vec3d& a, const cv::Vec3d& b) {
  return std::acos(std::min(1.0, std::abs(a.dot(b)))) * 180 / kPi;
}

int count(const MeshTurns& t, MeshTurn::Kind kind) {
  int n = 0;
  for (const MeshTurn& m : t.alternatives) n += m.kind == kind;
  return n;
}

MeshTurns analyse(const Mesh& m) { return find_mesh_turns(m, SurfaceGrid(m, 0.25, 0.5)); }

// A hex head (six-sided prism) on a round shank: 6-fold about its axis and nothing else, so it is
// checked turned over about an axis across it and by +-0.4 of 60 degrees about its own.
Mesh hex_bolt() {
  Mesh bolt;
  add(bolt, make_cylinder(10, 6, 6), cv::Matx33d::eye(), {0, 0, 3});
  add(bolt, make_cylinder(4, 30, 48), cv::Matx33d::eye(), {0, 0, -15});
  return moved(bolt, kFrame, kShift);
}

TEST(MeshTurns, SamplesLieOnTheSurfaceAndCoverItByArea) {
  const Mesh box = make_box(40, 20, 10);
  const auto points = sample_surface(box, 2000);
  ASSERT_EQ(points.size(), 2000u);
  int top = 0;
  for (const cv::Vec3d& p : points) {
    EXPECT_LT(distance_to_surface(box, p), 1e-6);
    top += std::abs(p[2] - 5) < 1e-6;
  }
  // The top face holds 800 of the 2800 mm^2.
  EXPECT_NEAR(top / 2000.0, 800.0 / 2800.0, 0.02);
}

TEST(MeshTurns, AxisRotationIsRodrigues) {
  const cv::Matx33d R = axis_rotation({0, 0, 1}, kPi / 2);
  const cv::Vec3d x = R * cv::Vec3d(1, 0, 0);
  EXPECT_NEAR(x[1], 1, 1e-12);
  const cv::Matx33d S = axis_rotation(cv::normalize(cv::Vec3d(1, 2, 3)), 1.1);
  EXPECT_LT(cv::norm(S * S.t() - cv::Matx33d::eye()), 1e-12);
  EXPECT_NEAR(cv::determinant(S), 1, 1e-12);
}

TEST(MeshTurns, BoxHasThreeHalfTurnSymmetriesAndNothingToCheck) {
  const MeshTurns t = analyse(moved(make_box(40, 20, 10), kFrame, kShift));
  ASSERT_EQ(t.symmetries.size(), 3u);
  for (const MeshTurn& s : t.symmetries) EXPECT_EQ(s.order, 2);
  EXPECT_EQ(count(t, MeshTurn::Kind::turn_over), 0);
  EXPECT_EQ(count(t, MeshTurn::Kind::near_symmetry), 0);
  EXPECT_EQ(count(t, MeshTurn::Kind::phase), 0);
  EXPECT_LT(cv::norm(t.centroid_mm - kShift), 0.2);
}

TEST(MeshTurns, HexBoltIsSixFoldAboutItsAxisWhereverTheFrameIs) {
  const MeshTurns t = analyse(hex_bolt());
  const cv::Vec3d axis = kFrame * cv::Vec3d(0, 0, 1);
  ASSERT_FALSE(t.symmetries.empty());
  const MeshTurn* six = nullptr;
  for (const MeshTurn& s : t.symmetries)
    if (axis_deg(s.axis, axis) < 0.5) six = &s;
  ASSERT_NE(six, nullptr) << "the bolt's axis, in the rotated frame";
  EXPECT_EQ(six->order, 6);
  // The axis passes through the part: the pivot lies on it.
  const cv::Vec3d off = six->pivot_mm - kShift;
  EXPECT_LT(cv::norm(off - axis * off.dot(axis)), 0.3);
  EXPECT_EQ(count(t, MeshTurn::Kind::phase), 2);
  for (const MeshTurn& m : t.alternatives)
    if (m.kind == MeshTurn::Kind::phase) {
      EXPECT_LT(axis_deg(m.axis, axis), 0.5);
    }
  // Turned over: head down. One turn across the axis (the others are the same modulo the six turns).
  ASSERT_GE(count(t, MeshTurn::Kind::turn_over), 1);
  for (const MeshTurn& m : t.alternatives)
    if (m.kind == MeshTurn::Kind::turn_over) {
      EXPECT_GT(axis_deg(m.axis, axis), 85);
    }
}

TEST(MeshTurns, GearWithOneOddToothIsANearSymmetryOfTwelveTurns) {
  // Twelve teeth round a disc, one of them longer: every turn by a multiple of 30 degrees maps all
  // but that tooth onto the part.
  Mesh gear = make_cylinder(20, 8, 96);
  for (int k = 0; k < 12; ++k) {
    const cv::Matx33d R = axis_rotation({0, 0, 1}, 2 * kPi * k / 12);
    add(gear, make_box(k == 0 ? 12 : 6, 4, 8), R, R * cv::Vec3d(k == 0 ? 24 : 21, 0, 0));
  }
  const MeshTurns t = analyse(moved(gear, kFrame, kShift));
  const cv::Vec3d axis = kFrame * cv::Vec3d(0, 0, 1);
  // About the gear's axis, the eleven tooth turns; about axes across it, the gear turned over
  // (exact about the axis through the odd tooth, a near-symmetry about the others).
  int about_axis = 0;
  for (const MeshTurn& m : t.alternatives)
    if (m.kind == MeshTurn::Kind::near_symmetry && axis_deg(m.axis, axis) > 85) {
      EXPECT_EQ(m.order, 2);
    } else if (m.kind == MeshTurn::Kind::near_symmetry) {
      ++about_axis;
      EXPECT_LT(axis_deg(m.axis, axis), 0.5);
      EXPECT_EQ(m.order, 12);
      EXPECT_GE(m.on_surface, 0.6);
      EXPECT_LT(m.on_surface, 0.99);
    }
  EXPECT_EQ(about_axis, 11);
  EXPECT_EQ(count(t, MeshTurn::Kind::phase), 2);
}

TEST(MeshTurns, LopsidedBlockIsCheckedTurnedOverAboutEachPrincipalAxis) {
  // Three boxes of different sizes in a corner: no turn maps much of it onto itself.
  Mesh block = make_box(40, 20, 10);
  add(block, make_box(10, 10, 14), cv::Matx33d::eye(), {15, 5, 10});
  add(block, make_box(6, 18, 6), cv::Matx33d::eye(), {-17, 0, -8});
  const MeshTurns t = analyse(moved(block, kFrame, kShift));
  EXPECT_TRUE(t.symmetries.empty());
  EXPECT_EQ(count(t, MeshTurn::Kind::turn_over), 3);
  EXPECT_EQ(count(t, MeshTurn::Kind::phase), 0);
}

TEST(MeshTurns, BadParametersAreNamed) {
  MeshTurnParams p;
  p.near_share = 0.99;
  p.symmetry_share = 0.9;
  try {
    p.validate();
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("near_share"), std::string::npos);
  }
  EXPECT_THROW(find_mesh_turns(Mesh{}, SurfaceGrid(make_box(1, 1, 1), 0.25, 0.5)), std::invalid_argument);
}

}  // namespace
}  // namespace mfcd::vision
