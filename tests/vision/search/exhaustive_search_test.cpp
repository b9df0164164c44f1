#include <gtest/gtest.h>

#include <random>

#include "tests/vision/support/synthetic.hpp"
#include "vision/search/exhaustive_search.hpp"
#include "vision/search/nms.hpp"

using namespace mfcd::vision;
using namespace mfcd::vision::testing;

namespace {
struct Scene {
  cv::Mat1b map;
  DirectionalDistanceTransform dt3;
  IntegralDistanceTransform idt;
  ChamferCosts costs;
  std::vector<OrientedTemplate> templates;
};

// A query holding a rotated copy of a random template plus clutter, and the hypothesis set of
// that template (every 10 channels = 30 degrees, two scales).
void makeScene(std::mt19937& rng, Scene& s, cv::Size size) {
  Dt3Params p;
  const LineSet set = randomLineSet(rng, p.q, 10, 5, 30, 18);
  s.map = randomChannelMap(rng, size, p.q, 12, 20);
  const OrientedTemplate planted = orientTemplate(set, 0, Warp{10 * OrientationChannels(p.q).step() * 4, 1, 1});
  LineSet rotated;
  rotated.q = p.q;
  rotated.lines = planted.lines;
  drawLineSet(s.map, rotated, {size.width / 2.0, size.height / 2.0});
  s.dt3.compute(s.map, p);
  s.idt.compute(s.dt3);
  s.costs.compute(s.map, p);
  WarpGrid grid;
  grid.angleStepChannels = 10;
  grid.scales = {0.9, 1.0};
  s.templates.clear();
  for (const Warp& w : grid.warps(p.q)) s.templates.push_back(orientTemplate(set, 0, w));
}

void expectSame(const SearchResult& a, const SearchResult& b, const char* what) {
  ASSERT_EQ(a.candidates.size(), b.candidates.size()) << what;
  for (size_t i = 0; i < a.candidates.size(); ++i) {
    EXPECT_EQ(a.candidates[i].oriented, b.candidates[i].oriented) << what << " #" << i;
    EXPECT_EQ(a.candidates[i].tx, b.candidates[i].tx) << what << " #" << i;
    EXPECT_EQ(a.candidates[i].ty, b.candidates[i].ty) << what << " #" << i;
    EXPECT_EQ(a.candidates[i].sum, b.candidates[i].sum) << what << " #" << i;
  }
}

SearchParams params(SearchMode mode, double tau, bool hyp, bool spatial, int threads) {
  SearchParams p;
  p.mode = mode;
  p.threshold = tau;
  p.hypothesisBound = hyp;
  p.spatialBound = spatial;
  p.threads = threads;
  return p;
}
}  // namespace

// The bounded searches return exactly the unbounded exhaustive search's answer, and the fast
// FDCM search returns exactly what the obviously-right direct DCM search returns.
TEST(ExhaustiveSearch, BoundedLocalisationEqualsUnbounded) {
  std::mt19937 rng(31);
  uint64_t skipped = 0, evaluatedBounded = 0, evaluatedAll = 0;
  for (int trial = 0; trial < 6; ++trial) {
    Scene s;
    makeScene(rng, s, {110, 90});
    const FdcmMatcher fdcm(s.idt);
    const DirectDcmMatcher direct(s.dt3);
    const auto reference = exhaustiveSearch(direct, s.templates, params(SearchMode::Best, INFINITY, false, false, 1));
    ASSERT_EQ(reference.candidates.size(), 1u);
    for (int threads : {1, 2}) {
      for (auto [hyp, spatial] : {std::pair{false, false}, {true, false}, {false, true}, {true, true}}) {
        const auto r = exhaustiveSearch(fdcm, s.templates, params(SearchMode::Best, INFINITY, hyp, spatial, threads));
        expectSame(r, reference, "fdcm best");
        EXPECT_EQ(r.stats.hypotheses, reference.stats.hypotheses);
        if (hyp && spatial) {
          skipped += r.stats.skipped;
          evaluatedBounded += r.stats.segments;
          evaluatedAll += reference.stats.segments;
        }
      }
    }
    // With a finite threshold, bounds still agree (and may return nothing).
    const double tau = reference.candidates[0].cost() + 0.01;
    const auto a = exhaustiveSearch(fdcm, s.templates, params(SearchMode::Best, tau, true, true, 2));
    expectSame(a, reference, "fdcm best under threshold");
    const auto none = exhaustiveSearch(fdcm, s.templates,
                                       params(SearchMode::Best, reference.candidates[0].cost() - 0.01, true, true, 2));
    EXPECT_TRUE(none.candidates.empty());
  }
  EXPECT_GT(skipped, 0u) << "the spatial bound must skip something on these scenes";
  EXPECT_LT(evaluatedBounded * 3, evaluatedAll) << "bounds must cut the segment evaluations";
}

TEST(ExhaustiveSearch, BoundedDetectionEqualsUnbounded) {
  std::mt19937 rng(77);
  for (int trial = 0; trial < 4; ++trial) {
    Scene s;
    makeScene(rng, s, {100, 90});
    const FdcmMatcher fdcm(s.idt);
    const DirectDcmMatcher direct(s.dt3);
    const double tau = 2.5;
    const auto reference = exhaustiveSearch(direct, s.templates, params(SearchMode::Detect, tau, false, false, 1));
    ASSERT_FALSE(reference.candidates.empty()) << "the planted copy is under the threshold";
    for (auto [hyp, spatial] : {std::pair{true, false}, {false, true}, {true, true}}) {
      const auto r = exhaustiveSearch(fdcm, s.templates, params(SearchMode::Detect, tau, hyp, spatial, 2));
      expectSame(r, reference, "fdcm detect");
      EXPECT_FALSE(r.truncated);
    }
    // A candidate cap keeps exactly the best ones.
    SearchParams capped = params(SearchMode::Detect, tau, true, true, 2);
    capped.maxCandidates = 3;
    auto r = exhaustiveSearch(fdcm, s.templates, capped);
    auto head = reference;
    head.candidates.resize(std::min<size_t>(3, head.candidates.size()));
    expectSame(r, head, "capped");
    EXPECT_EQ(r.truncated, reference.candidates.size() > 3);
  }
}

TEST(ExhaustiveSearch, BaselinesBoundedEqualUnbounded) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 4; ++trial) {
    Scene s;
    makeScene(rng, s, {100, 80});
    for (auto kind : {ChamferMatcher::Kind::Chamfer, ChamferMatcher::Kind::OrientedChamfer}) {
      const ChamferMatcher m(s.costs, kind);
      const auto reference = exhaustiveSearch(m, s.templates, params(SearchMode::Best, INFINITY, false, false, 1));
      const auto r = exhaustiveSearch(m, s.templates, params(SearchMode::Best, INFINITY, true, true, 2));
      expectSame(r, reference, kind == ChamferMatcher::Kind::Chamfer ? "cm" : "ocm");
      if (kind == ChamferMatcher::Kind::OrientedChamfer) {
        EXPECT_EQ(r.stats.skipped, 0u) << "OCM is not Lipschitz";
      }
      const auto d = exhaustiveSearch(m, s.templates, params(SearchMode::Detect, 3.0, false, false, 1));
      const auto db = exhaustiveSearch(m, s.templates, params(SearchMode::Detect, 3.0, true, true, 2));
      expectSame(db, d, "baseline detect");
    }
  }
}

TEST(ExhaustiveSearch, FindsThePlantedTemplate) {
  std::mt19937 rng(123);
  Scene s;
  makeScene(rng, s, {160, 140});
  const FdcmMatcher fdcm(s.idt);
  const auto r = exhaustiveSearch(fdcm, s.templates, params(SearchMode::Best, INFINITY, true, true, 2));
  ASSERT_EQ(r.candidates.size(), 1u);
  const auto& c = r.candidates[0];
  EXPECT_LT(c.cost(), 0.5);
  EXPECT_NEAR(s.templates[c.oriented].warp.angle, 40 * OrientationChannels(60).step(), 1e-9);
  EXPECT_DOUBLE_EQ(s.templates[c.oriented].warp.scale, 1.0);
  EXPECT_LE(std::abs(c.tx - 80), 1);
  EXPECT_LE(std::abs(c.ty - 70), 1);
}

TEST(NonMaximumSuppression, KeepsTheCheapestOfOverlappingDetections) {
  OrientedTemplate t;
  t.x0 = -10;
  t.x1 = 10;
  t.y0 = -10;
  t.y1 = 10;
  t.pixels = 10;
  std::vector<OrientedTemplate> ts{t};
  std::vector<Candidate> cands{{0, 50, 50, 10, 10}, {0, 52, 51, 12, 10}, {0, 90, 50, 15, 10}, {0, 60, 50, 20, 10}};
  const auto kept = nonMaximumSuppression(cands, ts, 0.3, 10);
  ASSERT_EQ(kept.size(), 2u);
  EXPECT_EQ(kept[0].tx, 50);
  EXPECT_EQ(kept[1].tx, 90);
  EXPECT_EQ(nonMaximumSuppression(cands, ts, 0.3, 1).size(), 1u);
}
