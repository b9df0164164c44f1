#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "tests/hal/alloc_counter.hpp"
#include "tests/vision/support/synthetic.hpp"
#include "vision/search/oriented_template.hpp"

using namespace mfcd::vision;
using namespace mfcd::vision::testing;

// Every digital pixel of a warped template lies on its warped source segment (within the
// 0.5 px drift allowance, 0.5 px rounding and 1 px pattern anchoring), pixel counts match the
// segments' extents, spans fit 16-bit IDT3 sums, and the bounding box holds every pixel.
TEST(OrientedTemplate, DigitalPixelsFollowTheWarpedSegments) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> ua(-7, 7), us(0.5, 3.0), uas(0.8, 1.25);
  for (int trial = 0; trial < 200; ++trial) {
    const LineSet set = randomLineSet(rng, 60, 6, 2, 150, 80);
    const Warp w{ua(rng), us(rng), uas(rng)};
    const OrientedTemplate t = orientTemplate(set, 0, w);
    const OrientationChannels ch(60);
    const DigitalLineTable lines(ch, 2000, 2000);
    const cv::Matx22d A = w.matrix();
    std::vector<std::pair<cv::Point2d, cv::Point2d>> warped;
    double expectedPixels = 0;
    for (const auto& l : set.lines) {
      const cv::Vec2d a = A * cv::Vec2d(l.a.x, l.a.y), b = A * cv::Vec2d(l.b.x, l.b.y);
      if (cv::norm(b - a) < 1.0) continue;
      warped.emplace_back(cv::Point2d(a[0], a[1]), cv::Point2d(b[0], b[1]));
      expectedPixels += std::max(std::abs(b[0] - a[0]), std::abs(b[1] - a[1])) + 1;
    }
    EXPECT_NEAR(t.pixels, expectedPixels, 1.0 * warped.size() + 0.02 * expectedPixels);
    int total = 0;
    for (const auto& seg : t.segments) {
      EXPECT_LE(seg.span, kMaxSegmentSpan);
      // Translate far from the origin so the pattern table sees positive coordinates.
      forEachPixel(lines, seg.channel, seg.x + 1000, seg.y + 1000, seg.span, 0, [&](int x, int y) {
        const cv::Point2d p(x - 1000, y - 1000);
        double best = 1e9;
        for (const auto& [a, b] : warped) best = std::min(best, pointToSegment(p, a, b));
        EXPECT_LE(best, 0.5 + 0.5 + 1.0 + 1e-9) << "trial " << trial;
        EXPECT_GE(p.x, t.x0);
        EXPECT_LE(p.x, t.x1);
        EXPECT_GE(p.y, t.y0);
        EXPECT_LE(p.y, t.y1);
        ++total;
      });
    }
    EXPECT_EQ(total, t.pixels);
  }
}

TEST(WarpGrid, FullTurnInChannelStepsAndSeries) {
  WarpGrid g;
  EXPECT_EQ(g.warps(60).size(), 120u);
  g.angleStepChannels = 2;
  g.scales = WarpGrid::series(1.0, 1.2, 5);
  g.aspects = WarpGrid::series(1.0, 1.1, 3);
  EXPECT_EQ(g.warps(60).size(), 60u * 15u);
  EXPECT_NEAR(g.scales.front(), 1.0 / 1.44, 1e-12);
  EXPECT_NEAR(g.scales.back(), 1.44, 1e-12);
  EXPECT_NEAR(g.aspects[2] / g.aspects[1], 1.1, 1e-12);
  g.scales = {};
  EXPECT_THROW(g.warps(60), std::invalid_argument);
  g.scales = {1};
  g.angleStepChannels = 0;
  EXPECT_THROW(g.warps(60), std::invalid_argument);
}

// The reusing form (the pick cycle's local fits) gives exactly the returning form's template,
// whatever larger or smaller template was in `out` before, with most pixels first.
TEST(OrientedTemplate, ReusedOutputEqualsAFreshOne) {
  std::mt19937 rng(29);
  std::uniform_real_distribution<double> ua(-7, 7), us(0.3, 3.0);
  OrientedTemplate out;
  std::vector<DigitalSegment> scratch;
  for (int trial = 0; trial < 100; ++trial) {
    const LineSet set = randomLineSet(rng, 60, 1 + trial % 12, 2, 150, 80);
    const Warp w{ua(rng), us(rng), 1.0};
    const OrientedTemplate fresh = orientTemplate(set, trial, w);
    orientTemplate(set, trial, w, out, scratch);
    ASSERT_EQ(out.segments.size(), fresh.segments.size()) << "trial " << trial;
    for (size_t i = 0; i < out.segments.size(); ++i) {
      const DigitalSegment &a = out.segments[i], &b = fresh.segments[i];
      EXPECT_TRUE(a.x == b.x && a.y == b.y && a.channel == b.channel && a.span == b.span)
          << "trial " << trial << " segment " << i;
      if (i > 0) {
        EXPECT_GE(out.segments[i - 1].span, a.span);
      }
    }
    ASSERT_EQ(out.lines.size(), fresh.lines.size());
    for (size_t i = 0; i < out.lines.size(); ++i) EXPECT_EQ(out.lines[i].a, fresh.lines[i].a);
    EXPECT_EQ(out.pixels, fresh.pixels);
    EXPECT_EQ(out.templateIndex, trial);
    EXPECT_TRUE(out.x0 == fresh.x0 && out.x1 == fresh.x1 && out.y0 == fresh.y0 && out.y1 == fresh.y1);
  }
}

// After reserveOrientedTemplate for a stretch, digitising under any warp up to it allocates
// nothing, however long and however turned the lines (many one-pixel pieces at steep drifts).
TEST(OrientedTemplate, ReservedForAStretchNeverGrows) {
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> ua(-7, 7), us(0.2, 1.0), uaspect(0.5, 2.0);
  for (int trial = 0; trial < 60; ++trial) {
    const LineSet set = randomLineSet(rng, 60, 1 + trial % 12, 2, 150, 80);
    const double max_stretch = 3.0;
    OrientedTemplate out;
    std::vector<DigitalSegment> scratch;
    reserveOrientedTemplate(set, max_stretch, out, scratch);
    const auto before = mfcd::hal::test::allocation_count();
    for (int k = 0; k < 20; ++k) {
      // scale * max(aspect, 1) <= max_stretch: the warp's largest singular value
      const double aspect = uaspect(rng), scale = max_stretch * us(rng) / std::max(1.0, aspect);
      orientTemplate(set, trial, Warp{ua(rng), scale, aspect}, out, scratch);
    }
    EXPECT_EQ(mfcd::hal::test::allocation_count() - before, 0u) << "trial " << trial;
  }
}
