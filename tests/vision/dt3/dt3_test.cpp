#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "tests/vision/support/synthetic.hpp"
#include "vision/dt3/directional_distance_transform.hpp"

using namespace mfcd::vision;
using namespace mfcd::vision::testing;

// Twin: Eq. 8 evaluated directly, min over every edge pixel of distance + lambda * channel
// distance, in the same fixed point (exact integer equality) and in floating point (within the
// 1/16 px rounding of the storage).
TEST(Dt3, EqualsBruteForceMinimumOverEdgePixels) {
  std::mt19937 rng(2024);
  const int qs[] = {1, 2, 7, 16, 60};
  // One transform for every trial, as the pipeline keeps one: its kept buffers (edge pixels per
  // channel, per-thread scratch) must not carry anything from the previous size, q or map.
  DirectionalDistanceTransform dt3;
  for (int trial = 0; trial < 25; ++trial) {
    Dt3Params p;
    p.q = qs[trial % 5];
    p.lambda = std::array<double, 4>{0.5, 0.25, 1.0, 2.0}[trial % 4];
    p.maxCost = std::array<double, 3>{30.0, 8.0, 15.5}[trial % 3];
    // Oriented channels (edge polarity, q over 2 pi) for some even q: only the channels'
    // directions change, the transform must not care.
    p.oriented = p.q % 2 == 0 && trial % 2 == 1;
    // ... with a polarity penalty: none (infinity), zero, or in between.
    if (p.oriented) p.polarityPenalty = std::array<double, 4>{INFINITY, 0.0, 2.5, 7.0}[(trial / 2) % 4];
    const cv::Size size(20 + static_cast<int>(rng() % 50), 15 + static_cast<int>(rng() % 40));
    const cv::Mat1b map =
        randomChannelMap(rng, size, p.q, static_cast<int>(rng() % 6), static_cast<int>(rng() % 10), p.oriented);
    dt3.compute(map, p);
    const auto edges = labelledPixels(map);
    const OrientationChannels ch(p.q, p.oriented);
    for (int c = 0; c < p.q; ++c)
      for (int y = 0; y < size.height; ++y)
        for (int x = 0; x < size.width; ++x) {
          int bestUnits = p.capUnits();
          double bestPx = p.maxCost;
          for (const auto& e : edges) {
            const double d = std::hypot(e[0] - x, e[1] - y);
            int orientation = p.lambdaUnits() * ch.distance(c, e[2]);
            double orientationPx = p.lambda * ch.distance(c, e[2]);
            if (p.oriented) {  // or the edge reversed, plus the penalty
              const int reversed = ch.distance(ch.wrap(c + p.q / 2), e[2]);
              orientation = std::min(orientation, p.lambdaUnits() * reversed + p.polarityPenaltyUnits());
              orientationPx = std::min(orientationPx, p.lambda * reversed + p.polarityPenalty);
            }
            const int units = static_cast<int>(std::lround(kCostScale * d)) + orientation;
            bestUnits = std::min(bestUnits, units);
            bestPx = std::min(bestPx, d + orientationPx);
          }
          ASSERT_EQ(dt3.at(c, x, y), bestUnits) << "trial " << trial << " c " << c << " at " << x << "," << y;
          ASSERT_NEAR(dt3.at(c, x, y) / double(kCostScale), bestPx, 0.5 / kCostScale + 1e-9);
        }
  }
}

// Oriented channels with a zero polarity penalty are the undirected transform: channel c of the
// oriented one equals channel c mod q/2 of the undirected one built from the same map with its
// channels taken mod q/2.
TEST(Dt3, OrientedWithoutPenaltyIsTheUndirectedTransform) {
  std::mt19937 rng(77);
  for (int trial = 0; trial < 4; ++trial) {
    Dt3Params oriented;
    oriented.q = 120;
    oriented.oriented = true;
    oriented.polarityPenalty = 0;
    Dt3Params undirected;
    undirected.q = 60;
    const cv::Mat1b map = randomChannelMap(rng, {90, 70}, 120, 8, 20, true);
    cv::Mat1b folded = map.clone();
    for (auto& v : folded)
      if (v != kNoChannel) v = static_cast<uchar>(v % 60);
    DirectionalDistanceTransform a, b;
    a.compute(map, oriented);
    b.compute(folded, undirected);
    for (int c = 0; c < 120; ++c)
      for (int y = 0; y < map.rows; ++y)
        for (int x = 0; x < map.cols; ++x) ASSERT_EQ(a.at(c, x, y), b.at(c % 60, x, y)) << c << " " << x << "," << y;
  }
}

TEST(Dt3, NoEdgesGivesTheTruncationEverywhere) {
  DirectionalDistanceTransform dt3;
  Dt3Params p;
  dt3.compute(cv::Mat1b(30, 40, kNoChannel), p);
  for (int c = 0; c < p.q; ++c)
    for (int y = 0; y < 30; ++y)
      for (int x = 0; x < 40; ++x) ASSERT_EQ(dt3.at(c, x, y), p.capUnits());
}

TEST(Dt3, OrientationPenaltyUsesPaperUnits) {
  // A single horizontal edge pixel: a query of the perpendicular channel (30 steps away) pays
  // 30 * 0.5 = 15 px, i.e. 6 degrees cost one pixel at q = 60.
  cv::Mat1b map(21, 21, kNoChannel);
  map(10, 10) = 0;
  DirectionalDistanceTransform dt3;
  dt3.compute(map, {});
  EXPECT_EQ(dt3.at(0, 10, 10), 0);
  EXPECT_EQ(dt3.at(2, 10, 10), 1 * kCostScale) << "2 channels = 6 degrees = 1 px";
  EXPECT_EQ(dt3.at(30, 10, 10), 15 * kCostScale);
  EXPECT_EQ(dt3.at(58, 10, 10), 1 * kCostScale) << "orientation wraps around";
  EXPECT_EQ(dt3.at(0, 13, 14), 5 * kCostScale);
}

TEST(Dt3, BadInputIsRefused) {
  DirectionalDistanceTransform dt3;
  Dt3Params p;
  EXPECT_THROW(dt3.compute(cv::Mat1b(), p), std::invalid_argument);
  p.q = 0;
  EXPECT_THROW(dt3.compute(cv::Mat1b(4, 4, kNoChannel), p), std::invalid_argument);
  p = {};
  p.maxCost = 40;
  EXPECT_THROW(dt3.compute(cv::Mat1b(4, 4, kNoChannel), p), std::invalid_argument);
  p = {};
  p.q = 9;
  p.oriented = true;
  EXPECT_THROW(dt3.compute(cv::Mat1b(10, 10, kNoChannel), p), std::invalid_argument) << "oriented needs an even q";
  p.q = 10;
  p.polarityPenalty = -1;
  EXPECT_THROW(dt3.compute(cv::Mat1b(10, 10, kNoChannel), p), std::invalid_argument);
  p.polarityPenalty = INFINITY;
  p.oriented = false;
  p.q = 10;
  cv::Mat1b map(4, 4, kNoChannel);
  map(1, 1) = 12;
  try {
    dt3.compute(map, p);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("channel 12 but q = 10"), std::string::npos);
  }
}
