#include <gtest/gtest.h>

#include <random>

#include "tests/vision/support/synthetic.hpp"
#include "vision/idt3/integral_distance_transform.hpp"

using namespace mfcd::vision;
using namespace mfcd::vision::testing;

// Twin: every segment's IDT3 cost (two reads) equals the sum of DT3 over its digital pixels.
TEST(Idt3, SegmentSumsEqualDirectSums) {
  std::mt19937 rng(99);
  // Kept across trials (sizes and q change), as the pipeline keeps them: a resize must rebuild the
  // line table and its per-column hops, a same-size compute must reuse them.
  DirectionalDistanceTransform dt3;
  IntegralDistanceTransform idt;
  cv::Size last_size;
  int last_q = 60;
  bool last_oriented = false;
  for (int trial = 0; trial < 16; ++trial) {
    Dt3Params p;
    p.q = trial % 3 == 0 ? 60 : 8 + trial;
    // Oriented channels (q over 2 pi, edge polarity): their own digital patterns, a channel and
    // its reverse sharing one. Trial 15 keeps trial 14's size and q = 120 but drops the
    // orientation: the table must be rebuilt for it.
    p.oriented = trial >= 12;
    if (p.oriented) p.q = 120;
    const cv::Size fresh(120 + static_cast<int>(rng() % 200), 90 + static_cast<int>(rng() % 200));
    const bool reuse = trial % 2 == 1;  // odd trials keep the previous size and q: the reuse path
    const cv::Size size = reuse ? last_size : fresh;
    if (reuse) p.q = last_q, p.oriented = trial == 15 ? !last_oriented : last_oriented;
    const cv::Mat1b map = randomChannelMap(rng, size, p.q, 15, 30, p.oriented);
    dt3.compute(map, p);
    idt.compute(dt3);
    last_size = size;
    last_q = p.q;
    last_oriented = p.oriented;
    int checked = 0;
    while (checked < 3000) {
      const int c = static_cast<int>(rng() % p.q);
      const int span = static_cast<int>(rng() % (kMaxSegmentSpan + 1));
      const int sx = static_cast<int>(rng() % size.width), sy = static_cast<int>(rng() % size.height);
      // The major extent must fit before the pattern table is read; the minor one is checked per pixel.
      if ((idt.lines().xMajor(c) ? sx : sy) + span >= (idt.lines().xMajor(c) ? size.width : size.height)) continue;
      bool inside = true;
      uint32_t direct = 0;
      forEachPixel(idt.lines(), c, sx, sy, span, 1, [&](int x, int y) {
        if (x < 0 || y < 0 || x >= size.width || y >= size.height)
          inside = false;
        else
          direct += dt3.at(c, x, y);
      });
      if (!inside) continue;
      ASSERT_EQ(idt.segmentCost(c, sx, sy, span), direct)
          << "trial " << trial << " channel " << c << " start " << sx << "," << sy << " span " << span;
      ++checked;
    }
  }
}

TEST(Idt3, LongestSegmentAtMaximumCostStaysExact) {
  // 256 pixels at the 255-unit maximum sum to 65280 < 2^16: exact despite 16-bit storage.
  Dt3Params p;
  p.maxCost = 31.875;
  DirectionalDistanceTransform dt3;
  dt3.compute(cv::Mat1b(600, 600, kNoChannel), p);
  IntegralDistanceTransform idt;
  idt.compute(dt3);
  for (int c = 0; c < p.q; ++c) {
    const bool xm = idt.lines().xMajor(c);
    const int sx = xm ? 10 : 300, sy = xm ? 300 : 10;
    EXPECT_EQ(idt.segmentCost(c, sx, sy, kMaxSegmentSpan), 256u * 255u) << "channel " << c;
  }
}
