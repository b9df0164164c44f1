// edge_tangents: the chain direction of every edge pixel against its obviously-right twin (the
// principal axis of the window's pixels by an eigen decomposition of their covariance), on
// straight chains of known direction, and oriented by a shadow map.
#include "vision/edges/edge_tangents.hpp"
#include "vision/common/orientation.hpp"
#include "vision/edges/depth_edges.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <stdexcept>

using namespace mfcd::vision;

namespace {

// The twin: the window's edge pixels, their covariance, its major eigenvector's angle.
double reference_tangent(const cv::Mat1b& edges, int x, int y, int radius) {
  std::vector<cv::Point2d> pts;
  for (int v = y - radius; v <= y + radius; ++v)
    for (int u = x - radius; u <= x + radius; ++u)
      if (u >= 0 && v >= 0 && u < edges.cols && v < edges.rows && edges(v, u)) pts.emplace_back(u, v);
  cv::Point2d mean(0, 0);
  for (const auto& p : pts) mean += p;
  mean *= 1.0 / static_cast<double>(pts.size());
  cv::Matx22d C = cv::Matx22d::zeros();
  for (const auto& p : pts) {
    const cv::Point2d d = p - mean;
    C += cv::Matx22d(d.x * d.x, d.x * d.y, d.x * d.y, d.y * d.y) * (1.0 / static_cast<double>(pts.size()));
  }
  cv::Mat values, vectors;
  cv::eigen(cv::Mat(C), values, vectors);  // descending: row 0 is the major axis
  return std::atan2(vectors.at<double>(0, 1), vectors.at<double>(0, 0));
}

cv::Mat1b random_edges(std::mt19937& rng, cv::Size size) {
  cv::Mat1b e(size, uchar(0));
  std::uniform_int_distribution<int> ux(0, size.width - 1), uy(0, size.height - 1);
  for (int i = 0; i < 12; ++i) cv::line(e, {ux(rng), uy(rng)}, {ux(rng), uy(rng)}, 255, 1);
  for (int i = 0; i < 6; ++i) cv::circle(e, {ux(rng), uy(rng)}, 5 + ux(rng) % 20, 255, 1);
  for (int i = 0; i < 60; ++i) e(uy(rng), ux(rng)) = 255;  // isolated and clustered noise
  return e;
}

}  // namespace

TEST(EdgeTangents, MatchReferenceOnRandomEdgeMaps) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 6; ++trial) {
    const cv::Mat1b e = random_edges(rng, cv::Size(160 + 17 * trial, 120 + 9 * trial));
    for (int radius : {1, 3}) {
      cv::Mat1f d;
      edge_tangents(e, d, radius);
      int compared = 0;
      for (int y = 0; y < e.rows; ++y)
        for (int x = 0; x < e.cols; ++x) {
          if (!e(y, x)) {
            ASSERT_EQ(d(y, x), 0.f);
            continue;
          }
          ASSERT_GE(d(y, x), 0.f);
          ASSERT_LT(d(y, x), std::numbers::pi_v<float>);
          ASSERT_FLOAT_EQ(d(y, x), edge_tangent_at(e, x, y, radius));
          // A window with (nearly) isotropic pixels has no principal axis: skip those.
          cv::Mat1b window =
              e(cv::Rect(x - radius, y - radius, 2 * radius + 1, 2 * radius + 1) & cv::Rect(0, 0, e.cols, e.rows));
          if (cv::countNonZero(window) < 3) continue;
          cv::Moments m = cv::moments(window, true);
          const double a = m.mu20 / m.m00, b = m.mu02 / m.m00, c = m.mu11 / m.m00;
          const double spread = std::sqrt((a - b) * (a - b) + 4 * c * c);
          if (spread < 0.2) continue;
          ++compared;
          ASSERT_LT(undirected_angle_difference(d(y, x), reference_tangent(e, x, y, radius)), 1e-4)
              << "trial " << trial << " radius " << radius << " at " << x << "," << y;
        }
      EXPECT_GT(compared, 300) << "trial " << trial;
    }
  }
}

TEST(EdgeTangents, StraightChainsHaveTheirDirection) {
  for (int deg = 0; deg < 180; deg += 15) {
    const double a = deg * std::numbers::pi / 180;
    cv::Mat1b e(101, 101, uchar(0));
    cv::line(e, cv::Point(cvRound(50 - 45 * std::cos(a)), cvRound(50 - 45 * std::sin(a))),
             cv::Point(cvRound(50 + 45 * std::cos(a)), cvRound(50 + 45 * std::sin(a))), 255, 1);
    cv::Mat1f d;
    edge_tangents(e, d);
    // Away from the chain's ends (their windows see half a line): the digital staircase turns a
    // 7x7 window's axis by a few degrees at most.
    double sum = 0, worst = 0;
    int n = 0;
    for (int y = 0; y < e.rows; ++y)
      for (int x = 0; x < e.cols; ++x)
        if (e(y, x) && std::hypot(x - 50, y - 50) < 40) {
          const double err = undirected_angle_difference(d(y, x), a);
          sum += err, worst = std::max(worst, err), ++n;
        }
    ASSERT_GT(n, 50);
    std::printf("%3d deg: mean error %.2f, worst %.2f deg\n", deg, sum / n * 180 / std::numbers::pi,
                worst * 180 / std::numbers::pi);
    EXPECT_LT(sum / n, 3 * std::numbers::pi / 180) << deg << " degrees";
    EXPECT_LT(worst, 6 * std::numbers::pi / 180) << deg << " degrees";
  }
}

// With a shadow map every tangent is the plain one turned so that its left normal points into
// the shadow; a shadow map of another size is refused.
TEST(EdgeTangents, OrientedByTheShadowSide) {
  std::mt19937 rng(9);
  const cv::Mat1b e = random_edges(rng, cv::Size(200, 150));
  cv::Mat1f shadow(e.size()), plain, oriented;
  cv::randu(shadow, 0.f, 2 * std::numbers::pi_v<float>);
  edge_tangents(e, plain);
  edge_tangents(e, oriented, 3, &shadow);
  for (int y = 0; y < e.rows; ++y)
    for (int x = 0; x < e.cols; ++x)
      ASSERT_EQ(oriented(y, x), e(y, x) ? oriented_tangent(plain(y, x), shadow(y, x)) : 0.f) << x << "," << y;
  const cv::Mat1f small(10, 10, 0.f);
  EXPECT_THROW(edge_tangents(e, oriented, 3, &small), std::invalid_argument);
}
