#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <queue>
#include <random>
#include <stdexcept>
#include <vector>

#include <omp.h>
#include <opencv2/imgproc.hpp>

#include "tests/hal/alloc_counter.hpp"
#include "tests/vision/support/synthetic.hpp"
#include "vision/lines/line_fitter.hpp"

using namespace mfcd::vision;
using namespace mfcd::vision::testing;

// Polygons with random edge directions (corners turning by 30..150 degrees, edges >= 40 px), drawn as 8-connected
// lines. Every fitted segment lies on a polygon edge: endpoints within 1 px of the edge's line,
// direction within one channel. Along the edge, an end may pass a vertex by up to 3 px: near a
// corner the two edges' pixels are within the fitting band of each other for a pixel or two
// (~ residual / sin(turn)), and the first segment accepted keeps them. The segments cover every
// edge except at most those corner pixels, and every vertex has a segment end within 3 px.
namespace {
// Bit for bit: the same segments in the same order and the same channel map.
bool same(const LineFitResult& a, const LineFitResult& b) {
  if (a.set.lines.size() != b.set.lines.size() || a.inputEdgePixels != b.inputEdgePixels ||
      a.explainedEdgePixels != b.explainedEdgePixels || cv::countNonZero(a.channelMap != b.channelMap) != 0)
    return false;
  for (size_t i = 0; i < a.set.lines.size(); ++i) {
    const LineSegment &p = a.set.lines[i], &q = b.set.lines[i];
    if (p.a != q.a || p.b != q.b || p.channel != q.channel || p.support != q.support) return false;
  }
  return true;
}
}  // namespace

TEST(LineFitter, RecoversRandomPolygons) {
  std::mt19937 rng(11);
  const OrientationChannels ch(60);
  int edgesChecked = 0;
  double worstPerpendicular = 0;
  for (int trial = 0; trial < 40; ++trial) {
    cv::Mat1b img(300, 300, uchar(0));
    const int nv = 3 + trial % 6;
    const auto poly = randomPolygon(rng, {150, 150}, 120, nv);
    std::vector<cv::Point> ipoly;
    for (const auto& p : poly) ipoly.emplace_back(cvRound(p.x), cvRound(p.y));
    cv::polylines(img, ipoly, true, 255, 1, cv::LINE_8);
    const LineFitResult r = fitLines(img);
    ASSERT_FALSE(r.set.lines.empty());
    std::vector<std::vector<std::pair<double, double>>> spans(nv);
    for (const auto& s : r.set.lines) {
      int best = -1;
      double bestD = 1e9;
      for (int i = 0; i < nv; ++i) {
        const double d = pointToSegment((cv::Point2d(s.a) + cv::Point2d(s.b)) * 0.5, poly[i], poly[(i + 1) % nv]);
        if (d < bestD) bestD = d, best = i;
      }
      const cv::Point2d a = poly[best], b = poly[(best + 1) % nv];
      const double len = cv::norm(b - a);
      const cv::Point2d u = (b - a) / len, n(-u.y, u.x);
      double t[2];
      int k = 0;
      for (const cv::Point2d e : {cv::Point2d(s.a), cv::Point2d(s.b)}) {
        const double perp = std::abs((e - a).dot(n));
        worstPerpendicular = std::max(worstPerpendicular, perp);
        EXPECT_LE(perp, 1.0) << "trial " << trial;
        t[k] = (e - a).dot(u);
        EXPECT_GE(t[k], -3.0) << "trial " << trial;
        EXPECT_LE(t[k], len + 3.0) << "trial " << trial;
        ++k;
      }
      EXPECT_LE(ch.distance(s.channel, ch.channelOf(std::atan2(u.y, u.x))), 1) << "trial " << trial;
      spans[best].emplace_back(std::min(t[0], t[1]), std::max(t[0], t[1]));
    }
    for (int i = 0; i < nv; ++i) {
      const double len = cv::norm(poly[(i + 1) % nv] - poly[i]);
      auto& sp = spans[i];
      std::sort(sp.begin(), sp.end());
      double covered = 0, reach = 0;
      for (auto [t0, t1] : sp) {
        t0 = std::max({t0, reach, 0.0});
        t1 = std::min(t1, len);
        if (t1 > t0) covered += t1 - t0;
        reach = std::max(reach, t1);
      }
      EXPECT_GE(covered, len - 6.0) << "trial " << trial << " edge " << i << " length " << len;
      double nearestEnd = 1e9;
      for (const auto& s : r.set.lines)
        nearestEnd = std::min({nearestEnd, cv::norm(cv::Point2d(s.a) - poly[i]), cv::norm(cv::Point2d(s.b) - poly[i])});
      EXPECT_LE(nearestEnd, 3.0) << "trial " << trial << " vertex " << i;
      ++edgesChecked;
    }
  }
  EXPECT_GT(edgesChecked, 150);
  std::printf("worst endpoint distance from its polygon edge line: %.3f px\n", worstPerpendicular);
}

// Edge polarity: the oriented fit is the undirected fit (same segments, same pixels), each
// segment turned so that its left normal points into the shadow side, which the majority of its
// pixels' shadow normals decides. Convex polygons, shadow outside (a part occludes what lies
// around it), a fifth of the pixels' shadow normals reversed as noise.
TEST(LineFitter, OrientedLinesAreTheUndirectedOnesTurnedTowardsTheShadow) {
  std::mt19937 rng(31);
  const OrientationChannels oriented(120, true);
  LineFitParams up, op;
  op.oriented = true;
  for (int trial = 0; trial < 12; ++trial) {
    cv::Mat1b img(300, 300, uchar(0));
    const cv::Point2d centre(150, 150);
    const auto poly = randomPolygon(rng, centre, 120, 3 + trial % 6);
    std::vector<cv::Point> ipoly;
    for (const auto& p : poly) ipoly.emplace_back(cvRound(p.x), cvRound(p.y));
    cv::polylines(img, ipoly, true, 255, 1, cv::LINE_8);
    cv::Mat1f shadow(img.size(), 0.f);
    const bool flipped = trial % 3 == 2;  // shadow inside: a hole's rim, every segment reversed
    for (int y = 0; y < img.rows; ++y)
      for (int x = 0; x < img.cols; ++x) {
        double a = std::atan2(y - centre.y, x - centre.x);
        if (flipped) a += CV_PI;
        if (rng() % 5 == 0) a += CV_PI;
        shadow(y, x) = static_cast<float>(a < 0 ? a + 2 * CV_PI : a >= 2 * CV_PI ? a - 2 * CV_PI : a);
      }
    const LineFitResult u = fitLines(img, up);
    const LineFitResult o = fitLines(img, op, nullptr, &shadow);
    EXPECT_FALSE(u.set.oriented);
    ASSERT_TRUE(o.set.oriented);
    ASSERT_EQ(o.set.q, 120);
    ASSERT_EQ(o.set.lines.size(), u.set.lines.size()) << "trial " << trial;
    ASSERT_FALSE(o.set.lines.empty());
    EXPECT_EQ(o.explainedEdgePixels, u.explainedEdgePixels);
    for (size_t i = 0; i < o.set.lines.size(); ++i) {
      const LineSegment &ol = o.set.lines[i], &ul = u.set.lines[i];
      EXPECT_EQ(ol.channel % 60, ul.channel) << "trial " << trial << " line " << i;
      EXPECT_EQ(ol.support, ul.support);
      const bool same = ol.a == ul.a && ol.b == ul.b, swapped = ol.a == ul.b && ol.b == ul.a;
      EXPECT_TRUE(same || swapped) << "the same endpoints, maybe swapped";
      const cv::Point2d d(ol.b - ol.a), left(-d.y, d.x), mid = (cv::Point2d(ol.a) + cv::Point2d(ol.b)) * 0.5;
      EXPECT_EQ(left.dot(mid - centre) > 0, !flipped) << "trial " << trial << ": left normal on the shadow side";
      EXPECT_EQ(oriented.channelOf(std::atan2(d.y, d.x)), ol.channel) << "a -> b is the channel's direction";
    }
    for (int y = 0; y < img.rows; ++y)
      for (int x = 0; x < img.cols; ++x) {
        const uchar oc = o.channelMap(y, x), uc = u.channelMap(y, x);
        ASSERT_EQ(oc == kNoChannel, uc == kNoChannel);
        if (oc != kNoChannel) {
          ASSERT_EQ(oc % 60, uc);
        }
      }
  }
  const cv::Mat1b some(20, 20, uchar(0));
  EXPECT_THROW(fitLines(some, op), std::invalid_argument) << "an oriented fit needs the shadow map";
  const cv::Mat1f small(10, 10, 0.f);
  EXPECT_THROW(fitLines(some, op, nullptr, &small), std::invalid_argument) << "of the edge map's size";
}

TEST(LineFitter, ChannelAlignedSegmentsComeBackWhole) {
  // A segment drawn exactly along a channel direction is one fitted segment with that channel,
  // its endpoints within 1 px of the drawn ones.
  const OrientationChannels ch(60);
  std::mt19937 rng(3);
  for (int c = 0; c < 60; ++c) {
    cv::Mat1b img(200, 200, uchar(0));
    const double phi = ch.angleOf(c);
    const cv::Point2d a(100 - 60 * std::cos(phi), 100 - 60 * std::sin(phi));
    const cv::Point2d b(100 + 60 * std::cos(phi), 100 + 60 * std::sin(phi));
    cv::line(img, cv::Point(cvRound(a.x), cvRound(a.y)), cv::Point(cvRound(b.x), cvRound(b.y)), 255, 1, cv::LINE_8);
    const LineFitResult r = fitLines(img);
    ASSERT_GE(r.set.lines.size(), 1u) << "channel " << c;
    const auto& s = r.set.lines.front();
    EXPECT_LE(ch.distance(s.channel, c), 1) << "channel " << c;
    EXPECT_GE(s.length(), 110) << "channel " << c;
    const double e1 = std::min(cv::norm(cv::Point2d(s.a) - a), cv::norm(cv::Point2d(s.a) - b));
    const double e2 = std::min(cv::norm(cv::Point2d(s.b) - a), cv::norm(cv::Point2d(s.b) - b));
    EXPECT_LE(e1, 1.5) << "channel " << c;
    EXPECT_LE(e2, 1.5) << "channel " << c;
  }
}

TEST(LineFitter, DropsIsolatedNoise) {
  std::mt19937 rng(5);
  cv::Mat1b img(240, 320, uchar(0));
  cv::line(img, {20, 200}, {300, 200}, 255);
  for (int i = 0; i < 400; ++i) img(static_cast<int>(rng() % 180), static_cast<int>(rng() % 320)) = 255;
  const LineFitResult r = fitLines(img);
  ASSERT_GE(r.set.lines.size(), 1u);
  EXPECT_EQ(r.set.lines.front().channel, 0);
  EXPECT_GE(r.set.lines.front().length(), 270);
  int noiseKept = 0;
  for (int y = 0; y < 180; ++y)
    for (int x = 0; x < 320; ++x) noiseKept += r.channelMap(y, x) != kNoChannel;
  EXPECT_LT(noiseKept, 20) << "isolated pixels must not survive as lines";
}

TEST(LineFitter, SortedLongestFirst) {
  std::mt19937 rng(9);
  cv::Mat1b img(300, 300, uchar(0));
  cv::rectangle(img, {40, 50}, {250, 120}, 255);
  cv::line(img, {30, 200}, {90, 260}, 255);
  const LineFitResult r = fitLines(img);
  for (size_t i = 1; i < r.set.lines.size(); ++i) EXPECT_GE(r.set.lines[i - 1].length(), r.set.lines[i].length());
}

TEST(LineFitter, BadInputIsRefused) {
  EXPECT_THROW(fitLines(cv::Mat1b()), std::invalid_argument);
  LineFitParams p;
  p.q = 0;
  EXPECT_THROW(fitLines(cv::Mat1b(10, 10, uchar(0)), p), std::invalid_argument);
  p = {};
  p.residual = 0;
  EXPECT_THROW(fitLines(cv::Mat1b(10, 10, uchar(0)), p), std::invalid_argument);
  p = {};
  p.minSupport = 1;
  EXPECT_THROW(fitLines(cv::Mat1b(10, 10, uchar(0)), p), std::invalid_argument);
  cv::Mat1f wrong(5, 5, 0.f);
  EXPECT_THROW(fitLines(cv::Mat1b(10, 10, uchar(0)), {}, &wrong), std::invalid_argument);
  EXPECT_TRUE(fitLines(cv::Mat1b(10, 10, uchar(0))).set.lines.empty()) << "no edges: no lines, no error";
}

// reduceQuery against the definition, pixel by pixel: a reduced pixel carries the channel of the
// first pixel of its block (row by row) that has one, on random sparse channel maps of sizes
// that are and are not multiples of the factor.
TEST(ReduceQuery, EveryBlockKeepsItsFirstChannel) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 24; ++trial) {
    const int factor = 1 + trial % 4;
    cv::Mat1b map(37 + trial, 50 + 3 * trial, kNoChannel);
    for (auto& v : map)
      if (rng() % 5 == 0) v = static_cast<uchar>(rng() % 60);
    LineSet lines, reduced;
    cv::Mat1b small;
    reduceQuery(lines, map, factor, reduced, small);
    ASSERT_EQ(small.cols, map.cols / factor);
    ASSERT_EQ(small.rows, map.rows / factor);
    for (int y = 0; y < small.rows; ++y)
      for (int x = 0; x < small.cols; ++x) {
        std::vector<uchar> block;
        for (int dy = 0; dy < factor; ++dy)
          for (int dx = 0; dx < factor; ++dx) block.push_back(map(y * factor + dy, x * factor + dx));
        const auto first = std::find_if(block.begin(), block.end(), [](uchar c) { return c != kNoChannel; });
        ASSERT_EQ(small(y, x), first == block.end() ? kNoChannel : *first)
            << "factor " << factor << " at " << x << "," << y;
      }
  }
}

// The reduced lines are the fitted lines scaled (channels and support kept), and each lies on the
// reduced channel map: every reduced line's pixels, sampled along it, are within one reduced pixel
// of a pixel carrying its channel.
TEST(ReduceQuery, LinesScaleOntoTheReducedMap) {
  std::mt19937 rng(23);
  cv::Mat1b img(300, 300, uchar(0));
  const auto poly = randomPolygon(rng, {150, 150}, 120, 6);
  std::vector<cv::Point> ipoly;
  for (const auto& p : poly) ipoly.emplace_back(cvRound(p.x), cvRound(p.y));
  cv::polylines(img, ipoly, true, 255);
  const LineFitResult fit = fitLines(img);
  ASSERT_FALSE(fit.set.lines.empty());
  for (int factor : {1, 2, 3}) {
    LineSet reduced;
    cv::Mat1b small;
    reduceQuery(fit.set, fit.channelMap, factor, reduced, small);
    if (factor == 1) {
      EXPECT_EQ(cv::countNonZero(small != fit.channelMap), 0) << "factor 1 is the identity";
    }
    ASSERT_EQ(reduced.lines.size(), fit.set.lines.size());
    EXPECT_EQ(reduced.size, cv::Size(300 / factor, 300 / factor));
    for (size_t i = 0; i < reduced.lines.size(); ++i) {
      const LineSegment& full = fit.set.lines[i];
      const LineSegment& l = reduced.lines[i];
      EXPECT_EQ(l.channel, full.channel);
      EXPECT_EQ(l.support, full.support);
      EXPECT_NEAR(l.a.x * factor, full.a.x, 1e-3);
      EXPECT_NEAR(l.b.y * factor, full.b.y, 1e-3);
      const int samples = std::max(2, static_cast<int>(l.length()));
      for (int k = 0; k <= samples; ++k) {
        const cv::Point2f p = l.a + (l.b - l.a) * (float(k) / samples);
        bool near = false;
        for (int dy = -1; dy <= 1 && !near; ++dy)
          for (int dx = -1; dx <= 1 && !near; ++dx) {
            const int x = cvRound(p.x) + dx, y = cvRound(p.y) + dy;
            near = x >= 0 && y >= 0 && x < small.cols && y < small.rows && small(y, x) != kNoChannel &&
                   std::abs(int(small(y, x)) - l.channel) <= 1;
          }
        EXPECT_TRUE(near) << "factor " << factor << " line " << i << " sample " << k;
      }
    }
  }
}

TEST(ReduceQuery, BadFactorIsRefused) {
  LineSet lines, reduced;
  cv::Mat1b small;
  EXPECT_THROW(reduceQuery(lines, cv::Mat1b(10, 10, kNoChannel), 0, reduced, small), std::invalid_argument);
  EXPECT_THROW(reduceQuery(lines, cv::Mat1b(2, 10, kNoChannel), 3, reduced, small), std::invalid_argument);
}

// LineFitter kept across calls (the pipeline's use) gives exactly fitLines' result, image after
// image, and once its buffers have grown to the largest image's needs it allocates nothing: no
// operator new (counted) and the same channel map storage.
TEST(LineFitter, ReusedGivesFitLinesResultWithoutAllocating) {
  std::mt19937 rng(31);
  std::vector<cv::Mat1b> images;
  std::vector<cv::Mat1f> directions;
  for (int k = 0; k < 8; ++k) {
    cv::Mat1b img(240, 320, uchar(0));
    cv::Mat1f dir(img.size(), 0.f);
    for (int p = 0; p < 1 + k % 3; ++p) {
      const auto poly = randomPolygon(rng, {80.0 + 80 * p, 120}, 60, 3 + (k + p) % 5);
      for (size_t i = 0; i < poly.size(); ++i) {
        const cv::Point a(cvRound(poly[i].x), cvRound(poly[i].y));
        const cv::Point b(cvRound(poly[(i + 1) % poly.size()].x), cvRound(poly[(i + 1) % poly.size()].y));
        double angle = std::atan2(double(b.y - a.y), double(b.x - a.x));
        if (angle < 0) angle += CV_PI;
        if (angle >= CV_PI) angle -= CV_PI;
        cv::line(img, a, b, 255);
        cv::line(dir, a, b, angle);
      }
    }
    images.push_back(img);
    directions.push_back(dir);
  }
  LineFitter fitter;
  LineFitResult out;
  for (size_t k = 0; k < images.size(); ++k) {
    fitter.fit(images[k], &directions[k], out);
    EXPECT_TRUE(same(out, fitLines(images[k], {}, &directions[k]))) << "image " << k;
    EXPECT_FALSE(out.set.lines.empty());
  }
  const uchar* storage = out.channelMap.data;
  const auto before = mfcd::hal::test::allocation_count();
  for (size_t k = 0; k < images.size(); ++k) fitter.fit(images[k], &directions[k], out);
  EXPECT_EQ(mfcd::hal::test::allocation_count() - before, 0u);
  EXPECT_EQ(out.channelMap.data, storage);
  EXPECT_TRUE(same(out, fitLines(images.back(), {}, &directions.back())));
}

// The hypotheses are scored on several threads: the result must not depend on how many. Dense
// clutter (crossing lines, polygons, noise) gives many equal scores, where only the
// hypotheses' total order (score, seed, channel) keeps the greedy choice the same.
TEST(LineFitter, OneThreadAndSeveralGiveTheSameLines) {
  std::mt19937 rng(47);
  std::uniform_int_distribution<int> ux(0, 399), uy(0, 299);
  for (int k = 0; k < 6; ++k) {
    cv::Mat1b img(300, 400, uchar(0));
    for (int i = 0; i < 25 + 10 * k; ++i) cv::line(img, {ux(rng), uy(rng)}, {ux(rng), uy(rng)}, 255);
    const auto poly = randomPolygon(rng, {200, 150}, 100, 3 + k);
    std::vector<cv::Point> ipoly;
    for (const auto& p : poly) ipoly.emplace_back(cvRound(p.x), cvRound(p.y));
    cv::polylines(img, ipoly, true, 255);
    for (int i = 0; i < 300; ++i) img(uy(rng), ux(rng)) = 255;
    const int before = omp_get_max_threads();
    omp_set_num_threads(1);
    const LineFitResult one = fitLines(img);
    omp_set_num_threads(3);
    const LineFitResult several = fitLines(img);
    omp_set_num_threads(before);
    EXPECT_GT(one.set.lines.size(), 20u) << "image " << k;
    EXPECT_TRUE(same(one, several)) << "image " << k;
  }
}

// The bucket queue against the obviously-right twin, one binary heap over LineFitter::Hypothesis
// (std::priority_queue, the fit's queue before): the same pops in the same order, for a bulk
// fill and then the greedy's pattern (pop, sometimes push the popped entry back with a lower
// score than the top's), with scores beyond the reserved range too.
TEST(HypothesisQueue, PopsInTheOrderOfOneBinaryHeap) {
  std::mt19937 rng(7);
  HypothesisQueue queue;  // reused, as the fit reuses it
  for (int trial = 0; trial < 200; ++trial) {
    std::priority_queue<LineFitter::Hypothesis> twin;
    const int seeds = std::uniform_int_distribution<int>(1, 400)(rng);
    const int max_score = std::uniform_int_distribution<int>(1, trial % 3 == 0 ? 5 : 300)(rng);
    queue.reset(trial % 4 == 0 ? max_score / 2 : max_score);
    std::uniform_int_distribution<int> score(0, max_score);
    // Unique (seed, channel) pairs, as the fit's: three channels per seed.
    for (int s = 0; s < seeds; ++s)
      for (int c : {s % 7, s % 7 + 7, s % 7 + 14}) {
        const int sc = score(rng);
        queue.add({sc, s, c});
        twin.push({sc, s, c});
      }
    queue.build();
    while (!twin.empty()) {
      ASSERT_FALSE(queue.empty());
      ASSERT_EQ(queue.top_score(), twin.top().score);
      const LineFitter::Hypothesis want = twin.top();
      twin.pop();
      const LineHypothesis got = queue.pop();
      ASSERT_EQ(got.score, want.score);
      ASSERT_EQ(got.seed, want.seed);
      ASSERT_EQ(got.channel, want.channel);
      // The greedy's re-scored hypothesis: lower than the top that is left.
      if (!twin.empty() && twin.top().score > 0 && std::uniform_int_distribution<int>(0, 1)(rng)) {
        const int lower = std::uniform_int_distribution<int>(0, twin.top().score - 1)(rng);
        queue.push({lower, got.seed, got.channel});
        twin.push({lower, got.seed, got.channel});
      }
    }
    EXPECT_TRUE(queue.empty());
    EXPECT_EQ(queue.top_score(), -1);
  }
}

TEST(HypothesisQueue, RefusesWhatWouldBreakItsOrder) {
  HypothesisQueue queue;
  queue.reset(10);
  EXPECT_THROW(queue.add({-1, 0, 0}), std::invalid_argument);
  queue.add({5, 0, 0});
  queue.add({3, 1, 0});
  queue.build();
  EXPECT_THROW(queue.push({5, 2, 0}), std::invalid_argument);  // at the top score
  EXPECT_THROW(queue.push({7, 2, 0}), std::invalid_argument);  // above it
  EXPECT_EQ(queue.pop().seed, 0);
  EXPECT_EQ(queue.pop().seed, 1);
  EXPECT_THROW(queue.pop(), std::logic_error);
}
