#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include <opencv2/imgproc.hpp>

#include "tests/hal/alloc_counter.hpp"
#include "vision/common/convex_region.hpp"

using namespace mfcd::vision;

namespace {

// Random point sets of the shapes the converse check meets, and the degenerate ones: clusters,
// repeats, points on one line, a single point; and dense sets (more than two points per row, as
// a placed template's), which build() first reduces to each row's two extremes.
std::vector<cv::Point> random_points(std::mt19937& rng, int trial) {
  std::vector<cv::Point> pts;
  const int kind = trial % 6;
  const int n = kind == 4 ? 1 : kind == 5 ? 200 + static_cast<int>(rng() % 800) : 2 + static_cast<int>(rng() % 60);
  const cv::Point c(static_cast<int>(rng() % 200), static_cast<int>(rng() % 200));
  const int spread = 1 + static_cast<int>(rng() % 40);
  for (int i = 0; i < n; ++i) {
    const int s = static_cast<int>(rng() % (2 * spread + 1)) - spread;
    const int t = static_cast<int>(rng() % (2 * spread + 1)) - spread;
    if (kind == 1)
      pts.emplace_back(c.x + s, c.y + 2 * s);  // one line
    else if (kind == 2)
      pts.emplace_back(c.x + s, c.y);  // one row
    else if (kind == 3)
      pts.push_back(i % 3 ? c : cv::Point(c.x + s, c.y + t));  // repeats
    else
      pts.emplace_back(c.x + s, c.y + t);
  }
  return pts;
}

// Exact: > 0 when a -> b -> p turns the same way as the monotone chain's hull.
long long turn(cv::Point a, cv::Point b, cv::Point p) {
  return static_cast<long long>(b.x - a.x) * (p.y - a.y) - static_cast<long long>(b.y - a.y) * (p.x - a.x);
}

// Twin of the covered test: does the closed unit square about (x, y) meet the convex polygon
// `poly` (vertices in order; a segment or a point when degenerate)? Separating axes: the square's
// two and each polygon edge's normal.
bool square_meets(const std::vector<cv::Point>& poly, int x, int y) {
  std::vector<cv::Point2d> axes{{1, 0}, {0, 1}};
  for (size_t i = 0; i < poly.size(); ++i) {
    const cv::Point d = poly[(i + 1) % poly.size()] - poly[i];
    if (d != cv::Point(0, 0)) axes.emplace_back(-d.y, d.x);
  }
  for (const auto& a : axes) {
    double lo = 1e18, hi = -1e18;
    for (const auto& p : poly) {
      const double v = a.x * p.x + a.y * p.y;
      lo = std::min(lo, v), hi = std::max(hi, v);
    }
    const double centre = a.x * x + a.y * y, half = 0.5 * (std::abs(a.x) + std::abs(a.y));
    if (centre + half < lo || centre - half > hi) return false;
  }
  return true;
}

// Builds `region` on `trials` random point sets and hands each set, with cv::convexHull's
// polygon of it as the independent reference, to `check`.
template <class Check>
void on_random_sets(unsigned seed, int trials, ConvexRegion& region, Check check) {
  std::mt19937 rng(seed);
  for (int trial = 0; trial < trials; ++trial) {
    const auto pts = random_points(rng, trial);
    region.build(pts);
    std::vector<cv::Point> reference;
    cv::convexHull(pts, reference);
    check(trial, pts, reference);
  }
}

}  // namespace

// The hull is the one polygon that is strictly convex, has input points as vertices, contains
// every input point and has cv::convexHull's area.
TEST(ConvexRegion, HullIsTheConvexHull) {
  ConvexRegion region;
  on_random_sets(11, 500, region, [&](int trial, const auto& pts, const auto& reference) {
    const auto& h = region.hull();
    ASSERT_FALSE(h.empty());
    for (const auto& v : h) ASSERT_NE(std::find(pts.begin(), pts.end(), v), pts.end());
    if (h.size() >= 3) {
      for (size_t i = 0; i < h.size(); ++i) {
        ASSERT_GT(turn(h[i], h[(i + 1) % h.size()], h[(i + 2) % h.size()]), 0) << "trial " << trial;
        for (const auto& p : pts) ASSERT_GE(turn(h[i], h[(i + 1) % h.size()], p), 0) << "trial " << trial;
      }
      EXPECT_DOUBLE_EQ(cv::contourArea(h), cv::contourArea(reference)) << "trial " << trial;
    } else {
      // Degenerate: every point on the segment (or the point) the hull is.
      for (const auto& p : pts) ASSERT_EQ(turn(h.front(), h.back(), p), 0) << "trial " << trial;
      EXPECT_DOUBLE_EQ(cv::contourArea(reference), 0.0);
    }
  });
}

// Twin: every pixel near the points tested against cv::convexHull's polygon by separating axes.
TEST(ConvexRegion, CoversExactlyThePixelsWhoseSquareMeetsTheHull) {
  ConvexRegion region;
  on_random_sets(5, 300, region, [&](int trial, const auto& pts, const auto& reference) {
    const cv::Rect box = cv::boundingRect(pts);
    ASSERT_EQ(region.top(), box.y);
    ASSERT_EQ(region.bottom(), box.y + box.height - 1);
    for (int y = box.y - 3; y < box.y + box.height + 3; ++y)
      for (int x = box.x - 3; x < box.x + box.width + 3; ++x) {
        const bool covered = y >= region.top() && y <= region.bottom() && x >= region.first(y) && x <= region.last(y);
        ASSERT_EQ(covered, square_meets(reference, x, y)) << "trial " << trial << " pixel " << x << "," << y;
      }
  });
}

TEST(ConvexRegion, EmptyInputGivesAnEmptyRegion) {
  ConvexRegion region;
  region.build(std::vector<cv::Point>{{3, 4}, {9, 9}, {3, 9}});
  region.build({});
  EXPECT_TRUE(region.empty());
  EXPECT_LT(region.bottom(), region.top());
}

TEST(ConvexRegion, ReusedBuildsWithoutAllocating) {
  std::mt19937 rng(3);
  std::vector<std::vector<cv::Point>> sets;
  for (int trial = 0; trial < 50; ++trial) sets.push_back(random_points(rng, trial));
  ConvexRegion region;
  for (const auto& s : sets) region.build(s);  // grow the buffers
  const auto before = mfcd::hal::test::allocation_count();
  for (const auto& s : sets) region.build(s);
  EXPECT_EQ(mfcd::hal::test::allocation_count() - before, 0u);
}
