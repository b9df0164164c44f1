#include <gtest/gtest.h>

#include <algorithm>

#include <cmath>
#include <random>

#include "tests/vision/support/synthetic.hpp"
#include "vision/search/matchers.hpp"

using namespace mfcd::vision;
using namespace mfcd::vision::testing;

namespace {
struct Query {
  cv::Mat1b map;
  DirectionalDistanceTransform dt3;
  IntegralDistanceTransform idt;
  ChamferCosts costs;
};
void build(Query& q, const Dt3Params& p) {
  q.dt3.compute(q.map, p);
  q.idt.compute(q.dt3);
  q.costs.compute(q.map, p);
}
template <class M>
uint32_t fullCost(const M& m, const OrientedTemplate& t, int tx, int ty) {
  typename M::State s;
  m.prepare(t, t.txMin(), t.txMax(m.width()), s);
  m.beginRow(s, ty);
  uint64_t segs = 0;
  return m.evaluate(s, tx, std::numeric_limits<uint32_t>::max(), segs);
}
}  // namespace

// FDCM (two IDT3 reads per segment) equals the direct DCM sum over the same template pixels,
// for random templates under random rotations, scales and aspects, at random translations.
TEST(FdcmMatcher, EqualsDirectDcmSum) {
  std::mt19937 rng(1);
  for (int trial = 0; trial < 14; ++trial) {
    Dt3Params p;
    if (trial >= 10) p.q = 120, p.oriented = true;  // edge polarity: 120 channels over 2 pi
    Query q;
    q.map = randomChannelMap(rng, {200, 160}, p.q, 25, 40, p.oriented);
    build(q, p);
    const FdcmMatcher fdcm(q.idt);
    const DirectDcmMatcher direct(q.dt3);
    const LineSet set = randomLineSet(rng, p.q, 12, 3, 60, 40, p.oriented);
    std::uniform_real_distribution<double> ua(0, 6.283), us(0.7, 1.3), uas(0.85, 1.15);
    for (int w = 0; w < 10; ++w) {
      const OrientedTemplate t = orientTemplate(set, 0, Warp{ua(rng), us(rng), uas(rng)});
      if (t.txMin() > t.txMax(200) || t.tyMin() > t.tyMax(160)) continue;
      for (int h = 0; h < 50; ++h) {
        const int tx = t.txMin() + static_cast<int>(rng() % (t.txMax(200) - t.txMin() + 1));
        const int ty = t.tyMin() + static_cast<int>(rng() % (t.tyMax(160) - t.tyMin() + 1));
        const uint32_t reference = fullCost(direct, t, tx, ty);
        ASSERT_EQ(fullCost(fdcm, t, tx, ty), reference) << "trial " << trial;
        // The scattered-translation entry point (1-D line search) is the same sum.
        uint64_t segs = 0;
        ASSERT_EQ(fdcm.evaluateAt(t, tx, ty, std::numeric_limits<uint32_t>::max(), segs), reference);
        // And from the entries a prefetch located (the line search's slides), for any count of them.
        const uint16_t* ends[2 * 64];
        const size_t count = static_cast<size_t>(h % 9) * 8;  // 0..64: none, some, all of them
        const size_t known = fdcm.prefetchAt(t, tx, ty, count, ends);
        ASSERT_EQ(known, std::min(count, t.segments.size()));
        ASSERT_EQ(fdcm.evaluateFrom(t, tx, ty, std::numeric_limits<uint32_t>::max(), segs, ends, known), reference);
        // Stopped early, it stops where evaluateAt does.
        uint64_t at_segs = 0, from_segs = 0;
        const uint32_t stop = reference / 3;
        ASSERT_EQ(fdcm.evaluateFrom(t, tx, ty, stop, from_segs, ends, known),
                  fdcm.evaluateAt(t, tx, ty, stop, at_segs));
        ASSERT_EQ(from_segs, at_segs);
      }
    }
  }
}

// The direct DCM sum is Eq. 6 on the template's pixels: mean of min over query edge pixels of
// distance + lambda * orientation difference (floating point, within the storage rounding).
TEST(DirectDcmMatcher, EqualsEquationSixOnTemplatePixels) {
  std::mt19937 rng(4);
  // Undirected (the paper's) and oriented channels (edge polarity: 120 over 2 pi, where a
  // template line next to the same edge reversed pays lambda * 60).
  for (const bool oriented : {false, true}) {
    Dt3Params p;
    p.oriented = oriented;
    if (oriented) p.q = 120;
    Query q;
    q.map = randomChannelMap(rng, {80, 70}, p.q, 6, 5, oriented);
    build(q, p);
    const OrientationChannels ch(p.q, oriented);
    const auto edges = labelledPixels(q.map);
    const DirectDcmMatcher direct(q.dt3);
    const DigitalLineTable lines(ch, 82, 72);
    for (int trial = 0; trial < 20; ++trial) {
      const LineSet set = randomLineSet(rng, p.q, 4, 3, 20, 12, oriented);
      const OrientedTemplate t = orientTemplate(set, 0, Warp{});
      const int tx = 20 + static_cast<int>(rng() % 40), ty = 20 + static_cast<int>(rng() % 30);
      double sum = 0;
      int n = 0;
      for (const auto& seg : t.segments)
        forEachPixel(lines, seg.channel, seg.x + tx, seg.y + ty, seg.span, 1, [&](int x, int y) {
          double best = p.maxCost;
          for (const auto& e : edges)
            best = std::min(best, std::hypot(e[0] - x, e[1] - y) + p.lambda * ch.distance(seg.channel, e[2]));
          sum += best;
          ++n;
        });
      ASSERT_EQ(n, t.pixels);
      const double dcm = sum / n;
      const double viaMatcher = fullCost(direct, t, tx, ty) / double(kCostScale * t.pixels);
      EXPECT_NEAR(viaMatcher, dcm, 0.5 / kCostScale + 1e-9) << "oriented " << oriented;
    }
  }
}

// CM and OCM against their definitions, straight from the edge pixels.
TEST(ChamferMatcher, CmAndOcmEqualTheirDefinitions) {
  std::mt19937 rng(8);
  Dt3Params p;
  Query q;
  q.map = randomChannelMap(rng, {90, 80}, p.q, 8, 6);
  build(q, p);
  const OrientationChannels ch(p.q);
  const auto edges = labelledPixels(q.map);
  const ChamferMatcher cm(q.costs, ChamferMatcher::Kind::Chamfer);
  const ChamferMatcher ocm(q.costs, ChamferMatcher::Kind::OrientedChamfer);
  for (int trial = 0; trial < 20; ++trial) {
    const LineSet set = randomLineSet(rng, p.q, 4, 3, 20, 12);
    const OrientedTemplate t = orientTemplate(set, 0, Warp{0.3 * trial, 1.0, 1.0});
    const int tx = 25 + static_cast<int>(rng() % 40), ty = 25 + static_cast<int>(rng() % 30);
    uint32_t cmDef = 0, ocmDef = 0;
    for (const auto& seg : t.segments) {
      // The baselines' template is a fixed point set: the pattern starts at each segment start.
      const double phi = ch.angleOf(seg.channel);
      const bool xm = ch.xMajor(seg.channel);
      const double slope = xm ? std::tan(phi) : 1.0 / std::tan(phi);
      for (int k = 0; k <= seg.span; ++k) {
        const int minor = static_cast<int>(std::floor(k * slope + 0.5));
        const int x = tx + (xm ? seg.x + k : seg.x + minor), y = ty + (xm ? seg.y + minor : seg.y + k);
        int bestD2 = 1 << 30;
        for (const auto& e : edges) bestD2 = std::min(bestD2, (e[0] - x) * (e[0] - x) + (e[1] - y) * (e[1] - y));
        const int d =
            std::min<int>(p.capUnits(), static_cast<int>(std::lround(kCostScale * std::sqrt(double(bestD2)))));
        cmDef += d;
        // The nearest edge's channel (ties between equidistant edges: the matcher's pick).
        const int nc = q.costs.nearestChannel(y, x);
        bool isNearest = false;
        for (const auto& e : edges)
          isNearest |= e[2] == nc && (e[0] - x) * (e[0] - x) + (e[1] - y) * (e[1] - y) == bestD2;
        EXPECT_TRUE(isNearest);
        ocmDef += std::min(p.capUnits(), d + p.lambdaUnits() * ch.distance(seg.channel, nc));
      }
    }
    EXPECT_EQ(fullCost(cm, t, tx, ty), cmDef);
    EXPECT_EQ(fullCost(ocm, t, tx, ty), ocmDef);
  }
}
