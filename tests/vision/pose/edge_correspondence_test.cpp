// DirectionalEdgeIndex (Eq. 21 correspondences) against its brute-force twin.
#include "vision/pose/edge_correspondence.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <random>

using namespace mfcd::vision;

namespace {

// Random edge map: line segments with their true tangent angle plus isolated noise pixels
// with random angles.
DepthEdges random_edges(std::mt19937& rng, cv::Size size, int segments, int noise) {
  DepthEdges e{cv::Mat1b(size, 0), cv::Mat1f(size, 0.f), {}};
  std::uniform_real_distribution<double> ux(0, size.width - 1), uy(0, size.height - 1), ua(0, CV_PI);
  for (int s = 0; s < segments; ++s) {
    const cv::Point a(static_cast<int>(ux(rng)), static_cast<int>(uy(rng)));
    const cv::Point b(static_cast<int>(ux(rng)), static_cast<int>(uy(rng)));
    double ang = std::atan2(b.y - a.y, b.x - a.x);
    if (ang < 0) ang += CV_PI;
    if (ang >= CV_PI) ang -= CV_PI;
    cv::LineIterator it(e.edges, a, b, 8);
    for (int i = 0; i < it.count; ++i, ++it) {
      e.edges(it.pos()) = 255;
      e.direction(it.pos()) = static_cast<float>(ang);
    }
  }
  for (int i = 0; i < noise; ++i) {
    const cv::Point p(static_cast<int>(ux(rng)), static_cast<int>(uy(rng)));
    e.edges(p) = 255;
    // Any angle: the index takes tangents modulo pi, as the brute force does.
    e.direction(p) = static_cast<float>(ua(rng) * 3 - CV_PI);
  }
  return e;
}

}  // namespace

TEST(EdgeCorrespondence, UndirectedAngleDifference) {
  EXPECT_NEAR(undirected_angle_difference(0.1, CV_PI - 0.1), 0.2, 1e-12);
  EXPECT_NEAR(undirected_angle_difference(0.0, CV_PI / 2), CV_PI / 2, 1e-12);
  EXPECT_NEAR(undirected_angle_difference(1.0, 1.0 + CV_PI), 0.0, 1e-12);
}

TEST(EdgeCorrespondence, OrientedAngleDifference) {
  EXPECT_NEAR(oriented_angle_difference(0.1, 2 * CV_PI - 0.1), 0.2, 1e-12);
  EXPECT_NEAR(oriented_angle_difference(1.0, 1.0 + CV_PI), CV_PI, 1e-12);
  EXPECT_NEAR(oriented_angle_difference(1.0, 1.0 + 4 * CV_PI), 0.0, 1e-12);
}

// Undirected (directions modulo pi) and oriented (modulo 2 pi, the occluder's side) alike.
TEST(EdgeCorrespondence, MatchesBruteForceOnRandomInputs) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 24; ++trial) {
    const bool oriented = trial % 2 == 1;
    const cv::Size size(97 + 15 * trial, 61 + 8 * trial);
    DepthEdges edges = random_edges(rng, size, 3 + trial / 2, 10 * trial);
    if (oriented)  // segment pixels have tangents in [0, pi): half of them turned to the other side
      for (int y = 0; y < size.height; ++y)
        for (int x = 0; x < size.width; ++x)
          if (edges.edges(y, x) && (x + y) % 2) edges.direction(y, x) += static_cast<float>(CV_PI);
    for (int cell : {1, 4, 8, 13}) {
      DirectionalEdgeIndex index(cell);
      index.build(edges, "edge map", oriented);
      // Query angles beyond [0, pi) too: a projected model tangent is not reduced modulo pi.
      std::uniform_real_distribution<double> ux(-20, size.width + 20), uy(-20, size.height + 20),
          ua(-2 * CV_PI, 3 * CV_PI), ug(0, 40), ul(0, 20);
      for (int q = 0; q < 300; ++q) {
        const cv::Point2d u(ux(rng), uy(rng));
        const double angle = ua(rng), gate = ug(rng), lambda = q % 5 == 0 ? 0.0 : ul(rng);
        const EdgeMatch fast = index.nearest(u, angle, lambda, gate);
        const EdgeMatch slow = nearest_edge_brute_force(edges, u, angle, lambda, gate, oriented);
        ASSERT_EQ(fast.found, slow.found) << "trial " << trial << " cell " << cell << " query " << q;
        if (!slow.found) continue;
        // 1e-5: an angle outside [0, pi) is stored reduced, in float.
        ASSERT_NEAR(fast.cost, slow.cost, 1e-5) << "trial " << trial << " cell " << cell << " query " << q;
        // Ties may pick another pixel; the pixel returned must attain the reported cost.
        ASSERT_TRUE(edges.edges(static_cast<int>(fast.y), static_cast<int>(fast.x)));
        const float d = edges.direction(static_cast<int>(fast.y), static_cast<int>(fast.x));
        const double check =
            std::hypot(fast.x - u.x, fast.y - u.y) +
            lambda * (oriented ? oriented_angle_difference(angle, d) : undirected_angle_difference(angle, d));
        ASSERT_NEAR(check, fast.cost, 1e-5);
      }
    }
  }
}

TEST(EdgeCorrespondence, OrientationTermPrefersParallelEdges) {
  // Two vertical-ish edges: a horizontal one 2 px away and a vertical one 4 px away. With
  // the paper's lambda (6 deg = 1 px), a vertical model edge matches the farther vertical one.
  DepthEdges e{cv::Mat1b(40, 40, uchar(0)), cv::Mat1f(40, 40, 0.f), {}};
  for (int y = 0; y < 40; ++y) {
    e.edges(y, 24) = 255;
    e.direction(y, 24) = static_cast<float>(CV_PI / 2);
  }
  for (int x = 0; x < 40; ++x) e.edges(22, x) = 255;  // direction 0 (horizontal)
  DirectionalEdgeIndex index;
  index.build(e);
  const EdgeMatch m = index.nearest({20, 20}, CV_PI / 2, kDefaultLambdaPxPerRad, 10);
  ASSERT_TRUE(m.found);
  EXPECT_EQ(m.x, 24);
  EXPECT_NEAR(m.cost, 4.0, 1e-5);  // the angle is stored as float
  const EdgeMatch none = index.nearest({20, 20}, CV_PI / 2, kDefaultLambdaPxPerRad, 1.5);
  EXPECT_FALSE(none.found);
}

// Oriented: two parallel vertical edges, the nearer one with its occluder on the other side. A
// model point pairs with the farther one, whose near side is its own; undirected, with the nearer.
TEST(EdgeCorrespondence, OrientedIndexPairsOnlyEdgesWithTheSameNearSide) {
  DepthEdges e{cv::Mat1b(40, 40, uchar(0)), cv::Mat1f(40, 40, 0.f), {}};
  for (int y = 0; y < 40; ++y) {
    e.edges(y, 22) = e.edges(y, 25) = 255;
    e.direction(y, 22) = static_cast<float>(CV_PI / 2);
    e.direction(y, 25) = static_cast<float>(3 * CV_PI / 2);
  }
  DirectionalEdgeIndex index;
  index.build(e, "edge map", true);
  EXPECT_TRUE(index.oriented());
  const EdgeMatch m = index.nearest({20, 20}, 3 * CV_PI / 2, kDefaultLambdaPxPerRad, 10);
  ASSERT_TRUE(m.found);
  EXPECT_EQ(m.x, 25);
  EXPECT_NEAR(m.cost, 5.0, 1e-5);
  index.build(e, "edge map", false);
  EXPECT_EQ(index.nearest({20, 20}, 3 * CV_PI / 2, kDefaultLambdaPxPerRad, 10).x, 22);
}

TEST(EdgeCorrespondence, BadInputIsRefusedWithItsName) {
  DirectionalEdgeIndex index;
  DepthEdges empty;
  try {
    index.build(empty, "view 3");
    FAIL() << "empty edge map accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("view 3"), std::string::npos) << e.what();
  }
  DepthEdges mismatched{cv::Mat1b(10, 10, uchar(0)), cv::Mat1f(9, 10, 0.f), {}};
  EXPECT_THROW(index.build(mismatched), std::invalid_argument);
  EXPECT_THROW(DirectionalEdgeIndex(0), std::invalid_argument);
  // No edge pixels: accepted, nothing found.
  DepthEdges blank{cv::Mat1b(10, 10, uchar(0)), cv::Mat1f(10, 10, 0.f), {}};
  index.build(blank);
  EXPECT_EQ(index.edge_count(), 0);
  EXPECT_FALSE(index.nearest({5, 5}, 0, 1, 100).found);
}
