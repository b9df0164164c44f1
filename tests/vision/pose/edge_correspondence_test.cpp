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
  DepthEdges e{cv::Mat1b(size, 0), cv::Mat1f(size, 0.f)};
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

TEST(EdgeCorrespondence, MatchesBruteForceOnRandomInputs) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 12; ++trial) {
    const cv::Size size(97 + 31 * trial, 61 + 17 * trial);
    const DepthEdges edges = random_edges(rng, size, 3 + trial, 20 * trial);
    for (int cell : {1, 4, 8, 13}) {
      DirectionalEdgeIndex index(cell);
      index.build(edges);
      // Query angles beyond [0, pi) too: a projected model tangent is not reduced modulo pi.
      std::uniform_real_distribution<double> ux(-20, size.width + 20), uy(-20, size.height + 20), ua(-2 * CV_PI, 3 * CV_PI),
          ug(0, 40), ul(0, 20);
      for (int q = 0; q < 300; ++q) {
        const cv::Point2d u(ux(rng), uy(rng));
        const double angle = ua(rng), gate = ug(rng), lambda = q % 5 == 0 ? 0.0 : ul(rng);
        const EdgeMatch fast = index.nearest(u, angle, lambda, gate);
        const EdgeMatch slow = nearest_edge_brute_force(edges, u, angle, lambda, gate);
        ASSERT_EQ(fast.found, slow.found) << "trial " << trial << " cell " << cell << " query " << q;
        if (!slow.found) continue;
        // 1e-5: an angle outside [0, pi) is stored reduced, in float.
        ASSERT_NEAR(fast.cost, slow.cost, 1e-5) << "trial " << trial << " cell " << cell << " query " << q;
        // Ties may pick another pixel; the pixel returned must attain the reported cost.
        ASSERT_TRUE(edges.edges(static_cast<int>(fast.y), static_cast<int>(fast.x)));
        const double check = std::hypot(fast.x - u.x, fast.y - u.y) +
                             lambda * undirected_angle_difference(angle, edges.direction(static_cast<int>(fast.y),
                                                                                         static_cast<int>(fast.x)));
        ASSERT_NEAR(check, fast.cost, 1e-5);
      }
    }
  }
}

TEST(EdgeCorrespondence, OrientationTermPrefersParallelEdges) {
  // Two vertical-ish edges: a horizontal one 2 px away and a vertical one 4 px away. With
  // the paper's lambda (6 deg = 1 px), a vertical model edge matches the farther vertical one.
  DepthEdges e{cv::Mat1b(40, 40, uchar(0)), cv::Mat1f(40, 40, 0.f)};
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

TEST(EdgeCorrespondence, BadInputIsRefusedWithItsName) {
  DirectionalEdgeIndex index;
  DepthEdges empty;
  try {
    index.build(empty, "view 3");
    FAIL() << "empty edge map accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("view 3"), std::string::npos) << e.what();
  }
  DepthEdges mismatched{cv::Mat1b(10, 10, uchar(0)), cv::Mat1f(9, 10, 0.f)};
  EXPECT_THROW(index.build(mismatched), std::invalid_argument);
  EXPECT_THROW(DirectionalEdgeIndex(0), std::invalid_argument);
  // No edge pixels: accepted, nothing found.
  DepthEdges blank{cv::Mat1b(10, 10, uchar(0)), cv::Mat1f(10, 10, 0.f)};
  index.build(blank);
  EXPECT_EQ(index.edge_count(), 0);
  EXPECT_FALSE(index.nearest({5, 5}, 0, 1, 100).found);
}
