#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <random>

#include <opencv2/imgproc.hpp>

#include "tests/vision/support/synthetic.hpp"
#include "vision/lines/line_fitter.hpp"
#include "vision/search/exhaustive_search.hpp"
#include "vision/search/line_search.hpp"

using namespace mfcd::vision;
using namespace mfcd::vision::testing;

namespace {

// A random line template planted at (160, 120), turned by a random whole number of channels,
// among random clutter; the query's lines and IDT3, and the template under every rotation.
struct PlantedScene {
  int rotation = 0;  // channels
  LineFitResult fit;
  IntegralDistanceTransform idt;
  std::vector<OrientedTemplate> templates;
};

// `oriented`: edge polarity (120 channels over 2 pi): the clutter's and the template's lines are
// oriented, and the query is fitted with a shadow map saying each pixel's shadow side (the left
// normal of its channel's direction).
PlantedScene plantedScene(std::mt19937& rng, bool oriented = false) {
  const OrientationChannels ch(oriented ? 120 : 60, oriented);
  Dt3Params p;
  p.q = ch.q();
  p.oriented = oriented;
  PlantedScene scene;
  const LineSet set = randomLineSet(rng, p.q, 8, 15, 60, 35, oriented);
  scene.rotation = static_cast<int>(rng() % 120);
  const OrientedTemplate planted = orientTemplate(set, 0, Warp{scene.rotation * ch.step(), 1, 1});
  LineSet drawn;
  drawn.q = p.q;
  drawn.oriented = oriented;
  drawn.lines = planted.lines;
  cv::Mat1b edges(240, 320, uchar(0));
  cv::Mat1b map = randomChannelMap(rng, edges.size(), p.q, 30, 50, oriented);
  drawLineSet(map, drawn, {160, 120});
  cv::Mat1f shadow(edges.size(), 0.f);
  for (int y = 0; y < map.rows; ++y)
    for (int x = 0; x < map.cols; ++x) {
      edges(y, x) = map(y, x) != kNoChannel ? 255 : 0;
      if (edges(y, x)) shadow(y, x) = static_cast<float>(std::fmod(ch.angleOf(map(y, x)) + CV_PI / 2, 2 * CV_PI));
    }
  LineFitParams lp;
  lp.oriented = oriented;
  scene.fit = fitLines(edges, lp, nullptr, oriented ? &shadow : nullptr);
  DirectionalDistanceTransform dt3;
  dt3.compute(scene.fit.channelMap, p);
  scene.idt.compute(dt3);
  WarpGrid grid;
  for (const Warp& w : grid.warps(p.q, oriented)) scene.templates.push_back(orientTemplate(set, 0, w));
  return scene;
}

// The 1-D search along major lines finds a planted, rotated template as well as the exhaustive
// search does, while evaluating far fewer hypotheses: over 8 random scenes, the planted copy in at
// least 7, and whenever the line search lands on it, its cost is within rounding of the
// exhaustive optimum.
void expectLineSearchFindsPlanted(uint32_t seed, bool oriented) {
  std::mt19937 rng(seed);
  int found = 0;
  for (int trial = 0; trial < 8; ++trial) {
    const PlantedScene scene = plantedScene(rng, oriented);
    const OrientationChannels ch(scene.idt.q(), oriented);
    ASSERT_EQ(scene.fit.set.oriented, oriented);
    ASSERT_EQ(scene.templates.size(), 120u) << "one template per 3-degree step over the full turn either way";
    const FdcmMatcher m(scene.idt);
    const SearchResult r = lineSearch(m, scene.templates, scene.fit.set.lines, LineSearchParams{});
    const SearchResult e = exhaustiveSearch(m, scene.templates, SearchParams{});
    ASSERT_EQ(e.candidates.size(), 1u);
    EXPECT_LT(r.stats.hypotheses * 20, e.stats.hypotheses) << "1-D search evaluates a small fraction";
    if (r.candidates.empty()) continue;
    const auto& c = r.candidates[0];
    const bool right = std::abs(c.tx - 160) <= 2 && std::abs(c.ty - 120) <= 2 &&
                       std::abs(std::remainder(scene.templates[c.oriented].warp.angle - scene.rotation * ch.step(),
                                               2 * CV_PI)) < 2.5 * ch.step();
    found += right;
    if (right) {
      EXPECT_LE(c.cost(), e.candidates[0].cost() + 0.35);
    }
  }
  EXPECT_GE(found, 7) << "planted template found in most trials";
}

}  // namespace

TEST(LineSearch, FindsPlantedTemplateWithFewHypotheses) { expectLineSearchFindsPlanted(42, false); }

// The same with edge polarity: the oriented 1-D search pairs a guide only with query lines of
// its own polarity (half the slides) and still lands on the planted copy.
TEST(LineSearch, OrientedSearchFindsPlantedTemplateWithFewHypotheses) { expectLineSearchFindsPlanted(43, true); }

// What polarity buys: a part's outline (shadow outside) and a hole of the same shape (shadow
// inside, as at a pocket's rim) give the same undirected edges. With oriented channels the
// outline template costs nothing on the outline and a lot on the hole, at every rotation;
// undirected it costs nothing on both.
TEST(LineSearch, OrientedCostsTellAnOutlineFromAHole) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 6; ++trial) {
    const auto poly = randomPolygon(rng, {0, 0}, 60, 4 + trial % 2);
    const cv::Point2d outline(100, 120), hole(300, 120);
    cv::Mat1b edges(240, 400, uchar(0));
    cv::Mat1f shadow(edges.size(), 0.f);
    for (const cv::Point2d at : {outline, hole}) {
      cv::Mat1b one(edges.size(), uchar(0));
      std::vector<cv::Point> ip;
      for (const auto& v : poly) ip.emplace_back(cvRound(v.x + at.x), cvRound(v.y + at.y));
      cv::polylines(one, ip, true, 255, 1, cv::LINE_8);
      for (int y = 0; y < one.rows; ++y)
        for (int x = 0; x < one.cols; ++x)
          if (one(y, x)) {
            edges(y, x) = 255;
            double a = std::atan2(y - at.y, x - at.x) + (at == hole ? CV_PI : 0.0);
            shadow(y, x) = static_cast<float>(a < 0 ? a + 2 * CV_PI : a >= 2 * CV_PI ? a - 2 * CV_PI : a);
          }
    }
    // The template: the polygon's edges, each running with its left normal outwards.
    LineSet tpl;
    tpl.q = 120;
    tpl.oriented = true;
    const OrientationChannels ch(120, true);
    for (size_t i = 0; i < poly.size(); ++i) {
      cv::Point2d a = poly[i], b = poly[(i + 1) % poly.size()];
      const cv::Point2d d = b - a;
      if (cv::Point2d(-d.y, d.x).dot((a + b) * 0.5) < 0) std::swap(a, b);
      LineSegment l;
      l.a = cv::Point2f(a);
      l.b = cv::Point2f(b);
      l.channel = ch.channelOf(std::atan2(l.b.y - l.a.y, l.b.x - l.a.x));
      tpl.lines.push_back(l);
    }
    for (const bool oriented : {true, false}) {
      LineFitParams lp;
      lp.oriented = oriented;
      const LineFitResult fit = fitLines(edges, lp, nullptr, &shadow);
      Dt3Params p;
      p.q = oriented ? 120 : 60;
      p.oriented = oriented;
      DirectionalDistanceTransform dt3;
      dt3.compute(fit.channelMap, p);
      IntegralDistanceTransform idt;
      idt.compute(dt3);
      const FdcmMatcher m(idt);
      const LineSet set = oriented ? tpl : withoutPolarity(tpl);
      // The lowest cost near each place over every rotation and +-2 px.
      double atOutline = 1e9, atHole = 1e9;
      for (const Warp& w : WarpGrid{}.warps(p.q, oriented)) {
        const OrientedTemplate t = orientTemplate(set, 0, w);
        for (int dy = -2; dy <= 2; ++dy)
          for (int dx = -2; dx <= 2; ++dx) {
            uint64_t segs = 0;
            const auto cost = [&](cv::Point2d at) {
              return m.evaluateAt(t, cvRound(at.x) + dx, cvRound(at.y) + dy, UINT32_MAX, segs) /
                     double(kCostScale * t.pixels);
            };
            atOutline = std::min(atOutline, cost(outline));
            atHole = std::min(atHole, cost(hole));
          }
      }
      EXPECT_LT(atOutline, 1.0) << "trial " << trial << " oriented " << oriented;
      if (oriented) {
        EXPECT_GT(atHole, 10.0) << "trial " << trial << ": the hole's edges have the other polarity";
      } else {
        EXPECT_LT(atHole, 1.0) << "trial " << trial << ": undirected, the hole matches as well";
      }
    }
  }
}

// Best mode keeping several hypotheses: against the same search in Detect mode (every visited
// hypothesis under the threshold, the obviously-right twin), the kept list starts with the
// overall best, is sorted, is pairwise more than the separation apart, and holds about as many
// places as a greedy selection from the full list.
TEST(LineSearch, KeepsSeveralSeparatedBestHypotheses) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 6; ++trial) {
    const PlantedScene scene = plantedScene(rng);
    const auto& fit = scene.fit;
    const auto& ts = scene.templates;
    const FdcmMatcher m(scene.idt);
    LineSearchParams lp;
    lp.threshold = 12;
    lp.keep = 5;
    lp.separationPx = 6;
    lp.hypothesisBound = false;  // every hypothesis fully evaluated: comparable with Detect
    const SearchResult r = lineSearch(m, ts, fit.set.lines, lp);
    lp.mode = SearchMode::Detect;
    const SearchResult all = lineSearch(m, ts, fit.set.lines, lp);
    ASSERT_FALSE(all.candidates.empty());
    ASSERT_FALSE(r.candidates.empty());
    ASSERT_LE(r.candidates.size(), 5u);
    const Candidate& first = r.candidates.front();
    EXPECT_EQ(first.tx, all.candidates.front().tx);
    EXPECT_EQ(first.ty, all.candidates.front().ty);
    EXPECT_EQ(first.sum * all.candidates.front().pixels, all.candidates.front().sum * first.pixels);
    for (size_t i = 0; i < r.candidates.size(); ++i)
      for (size_t j = i + 1; j < r.candidates.size(); ++j) {
        EXPECT_TRUE(better(r.candidates[i], r.candidates[j]));
        EXPECT_TRUE(std::abs(r.candidates[i].tx - r.candidates[j].tx) > 6 ||
                    std::abs(r.candidates[i].ty - r.candidates[j].ty) > 6);
      }
    // Greedy reference: the best of the visited hypotheses taken in order, skipping any near one
    // already taken. The streaming list may lose a place to a neighbour that is later displaced
    // itself, so it is not always equal; it must find as many places when the reference has
    // few, and at least half otherwise.
    std::vector<Candidate> greedy;
    for (const Candidate& c : all.candidates) {
      if (greedy.size() == 5) break;
      bool near = false;
      for (const Candidate& g : greedy) near = near || (std::abs(g.tx - c.tx) <= 6 && std::abs(g.ty - c.ty) <= 6);
      if (!near) greedy.push_back(c);
    }
    EXPECT_GE(2 * r.candidates.size(), greedy.size());
  }
}

// SharedCostBound::sumLimit is the largest sum over n pixels whose mean is not above the bound,
// checked against the definition on random ratios.
TEST(SharedCostBound, SumLimitIsTheLargestSumNotAboveTheBound) {
  std::mt19937 rng(7);
  EXPECT_EQ(SharedCostBound::sumLimit(SharedCostBound::kNone, 100), std::numeric_limits<uint32_t>::max());
  for (int i = 0; i < 2000; ++i) {
    const uint32_t sum = rng() % 200000, pixels = 1 + rng() % 3000;
    const int n = 1 + static_cast<int>(rng() % 3000);
    const uint32_t limit = SharedCostBound::sumLimit(SharedCostBound::pack(sum, pixels), n);
    // limit / n <= sum / pixels < (limit + 1) / n
    EXPECT_LE(uint64_t(limit) * pixels, uint64_t(sum) * n);
    EXPECT_GT(uint64_t(limit + 1) * pixels, uint64_t(sum) * n);
  }
}

// Threads lowering one bound at once leave the lowest ratio any of them offered.
TEST(SharedCostBound, ConcurrentLoweringKeepsTheMinimum) {
  std::atomic<uint64_t> bound{SharedCostBound::kNone};
  std::vector<std::pair<uint32_t, uint32_t>> offers;
  std::mt19937 rng(3);
  for (int i = 0; i < 4000; ++i) offers.emplace_back(1000 + rng() % 100000, 1 + rng() % 2000);
  double lowest = 1e18;
  for (const auto& [s, p] : offers) lowest = std::min(lowest, double(s) / p);
#pragma omp parallel for num_threads(4)
  for (int i = 0; i < static_cast<int>(offers.size()); ++i)
    SharedCostBound::lower(bound, offers[i].first, offers[i].second);
  const uint64_t b = bound.load();
  EXPECT_DOUBLE_EQ(double(b >> 32) / double(b & 0xffffffffu), lowest);
}

// A shared bound only removes what lies above it: at the best hypothesis' own cost the search
// returns that same hypothesis, one unit below it nothing.
TEST(LineSearch, SharedBoundKeepsEverythingNotAboveIt) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 6; ++trial) {
    const PlantedScene scene = plantedScene(rng);
    const FdcmMatcher matcher(scene.idt);
    LineSearchParams lp;
    lp.keep = 3;
    const SearchResult free = lineSearch(matcher, scene.templates, scene.fit.set.lines, lp);
    ASSERT_FALSE(free.candidates.empty());
    const Candidate& worst = free.candidates.back();
    std::atomic<uint64_t> bound{SharedCostBound::pack(worst.sum, static_cast<uint32_t>(worst.pixels))};
    lp.sharedBound = &bound;
    const SearchResult bounded = lineSearch(matcher, scene.templates, scene.fit.set.lines, lp);
    ASSERT_EQ(bounded.candidates.size(), free.candidates.size());
    for (size_t i = 0; i < free.candidates.size(); ++i) {
      EXPECT_EQ(bounded.candidates[i].oriented, free.candidates[i].oriented);
      EXPECT_EQ(bounded.candidates[i].tx, free.candidates[i].tx);
      EXPECT_EQ(bounded.candidates[i].ty, free.candidates[i].ty);
      EXPECT_EQ(bounded.candidates[i].sum, free.candidates[i].sum);
    }
    EXPECT_LE(bounded.stats.segments, free.stats.segments);
    const Candidate& best = free.candidates.front();
    if (best.sum == 0) continue;
    bound = SharedCostBound::pack(best.sum - 1, static_cast<uint32_t>(best.pixels));
    const SearchResult below = lineSearch(matcher, scene.templates, scene.fit.set.lines, lp);
    for (const Candidate& c : below.candidates)
      EXPECT_TRUE(better(c, best)) << "a hypothesis costing more than the bound was kept";
  }
}

// The reusing form (one workspace and result per search thread of the pipeline) returns exactly
// the returning form's result, scene after scene and mode after mode, whatever the workspace held.
TEST(LineSearch, ReusedWorkspaceGivesTheSameResult) {
  std::mt19937 rng(77);
  LineSearchWorkspace ws;
  SearchResult out;
  size_t detected = 0;
  for (int trial = 0; trial < 6; ++trial) {
    const PlantedScene scene = plantedScene(rng);
    const FdcmMatcher matcher(scene.idt);
    for (int variant = 0; variant < 3; ++variant) {
      LineSearchParams lp;
      lp.threshold = 6;
      lp.slideStep = 1 + variant;
      lp.mode = variant == 2 ? SearchMode::Detect : SearchMode::Best;
      lp.keep = variant == 1 ? 3 : 1;
      const SearchResult fresh = lineSearch(matcher, scene.templates, scene.fit.set.lines, lp);
      lineSearch(matcher, scene.templates, scene.fit.set.lines, lp, ws, out);
      ASSERT_EQ(out.candidates.size(), fresh.candidates.size()) << "trial " << trial << " variant " << variant;
      for (size_t i = 0; i < out.candidates.size(); ++i) {
        const Candidate &a = out.candidates[i], &b = fresh.candidates[i];
        EXPECT_TRUE(a.oriented == b.oriented && a.tx == b.tx && a.ty == b.ty && a.sum == b.sum && a.pixels == b.pixels)
            << "trial " << trial << " variant " << variant << " candidate " << i;
      }
      EXPECT_EQ(out.stats.evaluated, fresh.stats.evaluated);
      EXPECT_EQ(out.stats.hypotheses, fresh.stats.hypotheses);
      EXPECT_EQ(out.truncated, fresh.truncated);
      if (variant == 2) detected += out.candidates.size();
    }
  }
  EXPECT_GT(detected, 6u) << "Detect mode found (almost) nothing: the comparison would be empty";
}

// With a cap on the query lines' length, a template's guides slide along the longest query lines
// not longer than the cap times its longest guide: the same as the uncapped search over the query
// with the longer lines taken out (its slow twin), template by template.
TEST(LineSearch, QueryLinesTooLongForTheTemplateAreNotItsGuides) {
  std::mt19937 rng(91);
  size_t dropped = 0, detected = 0;
  for (int trial = 0; trial < 4; ++trial) {
    const PlantedScene scene = plantedScene(rng);
    const FdcmMatcher matcher(scene.idt);
    const std::vector<LineSegment>& query = scene.fit.set.lines;
    for (size_t o = 0; o < scene.templates.size(); o += 15) {
      const std::vector<OrientedTemplate> one{scene.templates[o]};
      LineSearchParams lp;
      lp.mode = SearchMode::Detect;
      lp.threshold = 12;
      lp.queryLines = 12;
      lp.templateLines = 3;
      float longest = 0;
      for (const LineSegment& l : one[0].lines) longest = std::max(longest, l.length());
      lp.maxQueryToGuide = 0.4;
      std::vector<LineSegment> short_enough;
      for (const LineSegment& l : query)
        if (l.length() <= lp.maxQueryToGuide * longest) short_enough.push_back(l);
      dropped += query.size() - short_enough.size();
      const SearchResult capped = lineSearch(matcher, one, query, lp);
      lp.maxQueryToGuide = std::numeric_limits<double>::infinity();
      const SearchResult twin = lineSearch(matcher, one, short_enough, lp);
      ASSERT_EQ(capped.candidates.size(), twin.candidates.size()) << "trial " << trial << " template " << o;
      for (size_t i = 0; i < capped.candidates.size(); ++i) {
        const Candidate &a = capped.candidates[i], &b = twin.candidates[i];
        EXPECT_TRUE(a.tx == b.tx && a.ty == b.ty && a.sum == b.sum) << "trial " << trial << " candidate " << i;
      }
      EXPECT_EQ(capped.stats.hypotheses, twin.stats.hypotheses);
      detected += capped.candidates.size();
    }
  }
  EXPECT_GT(dropped, 0u) << "no query line was longer than the cap: the test compares nothing";
  EXPECT_GT(detected, 0u) << "nothing detected: the comparison would be empty";
}
