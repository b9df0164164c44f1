// FDCM benchmarks (issue 2 / docs/benchmarks.md). All matching methods run over the same
// hypothesis sets on the same 640x480 cluttered query, single-threaded unless a name says
// otherwise, so ratios measured in one run compare like with like.
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>

#include <opencv2/imgproc.hpp>

#include "vision/detect/shape_detector.hpp"
#include "vision/dt3/directional_distance_transform.hpp"
#include "vision/idt3/integral_distance_transform.hpp"
#include "vision/search/exhaustive_search.hpp"
#include "vision/search/matchers.hpp"

using namespace mfcd::vision;

namespace {

const std::vector<cv::Point2d> kTNut{{-40, -30}, {40, -30}, {40, -10},  {15, -10},
                                     {15, 30},   {-15, 30}, {-15, -10}, {-40, -10}};

std::vector<cv::Point> place(const std::vector<cv::Point2d>& shape, cv::Point2d at, double angle, double scale = 1) {
  std::vector<cv::Point> out;
  const double c = std::cos(angle), s = std::sin(angle);
  for (const auto& p : shape)
    out.emplace_back(cvRound(at.x + scale * (c * p.x - s * p.y)), cvRound(at.y + scale * (s * p.x + c * p.y)));
  return out;
}

// Smooth random blob: a closed curve, so larger copies need more lines (Fig. 4 uses curved shapes).
std::vector<cv::Point2d> blob(std::mt19937& rng, double radius) {
  std::uniform_real_distribution<double> u(-1, 1);
  double a1 = u(rng) * 0.25, a2 = u(rng) * 0.15, a3 = u(rng) * 0.1, p1 = u(rng) * 3, p2 = u(rng) * 3, p3 = u(rng) * 3;
  std::vector<cv::Point2d> pts;
  const int n = std::max(24, static_cast<int>(radius * 2));
  for (int i = 0; i < n; ++i) {
    const double t = 2 * CV_PI * i / n;
    const double r = radius * (1 + a1 * std::cos(2 * t + p1) + a2 * std::cos(3 * t + p2) + a3 * std::cos(5 * t + p3));
    pts.emplace_back(r * std::cos(t), 0.7 * r * std::sin(t));
  }
  return pts;
}

// The query: a grey 640x480 scene with parts, 60 clutter lines and noise, through Canny and the
// line fitter, as the detector would see it.
struct Query {
  cv::Mat1b edges;
  LineFitResult fit;
  DirectionalDistanceTransform dt3;
  IntegralDistanceTransform idt;
  ChamferCosts costs;
  // clutter: number of random clutter segments (80: the dense default; 15: a typical depth-edge map)
  explicit Query(int clutter = 80, int blobs = 6) {
    std::mt19937 rng(1);
    cv::Mat1b img(480, 640, uchar(70));
    std::uniform_int_distribution<int> ux(0, 639), uy(0, 479), ug(30, 150);
    std::uniform_real_distribution<double> ua(0, CV_PI), ul(20, 160);
    // Clutter: 80 random segments of 20..160 px (the paper corrupts its depth-edge maps with
    // uniformly sampled line segments).
    for (int i = 0; i < clutter; ++i) {
      const cv::Point a(ux(rng), uy(rng));
      const double ang = ua(rng), len = ul(rng);
      cv::line(img, a, a + cv::Point(cvRound(len * std::cos(ang)), cvRound(len * std::sin(ang))), ug(rng), 1,
               cv::LINE_AA);
    }
    for (int k = 0; k < 8; ++k)
      cv::fillPoly(
          img,
          std::vector<std::vector<cv::Point>>{place(kTNut, {90.0 + (k % 4) * 150, 120.0 + (k / 4) * 230}, k * 0.7)},
          200);
    for (int k = 0; k < blobs; ++k) {
      std::vector<cv::Point> b;
      for (auto p : blob(rng, 30)) b.emplace_back(cvRound(p.x + ux(rng)), cvRound(p.y + uy(rng)));
      cv::polylines(img, std::vector<std::vector<cv::Point>>{b}, true, ug(rng), 2);
    }
    cv::Mat1s noise(img.size()), tmp;
    cv::randn(noise, 0, 5);
    img.convertTo(tmp, CV_16S);
    tmp += noise;
    tmp.convertTo(img, CV_8U);
    cv::Canny(img, edges, 50, 150, 3, true);
    fit = fitLines(edges);
    dt3.compute(fit.channelMap, {});
    idt.compute(dt3);
    costs.compute(fit.channelMap, {});
  }
};
const Query& query() {
  static const Query q;
  return q;
}
const Query& typicalQuery() {
  static const Query q(15, 2);
  return q;
}

LineSet tnutTemplate() {
  cv::Mat1b img(120, 120, uchar(0));
  cv::polylines(img, std::vector<std::vector<cv::Point>>{place(kTNut, {60, 60}, 0)}, true, 255, 1);
  return templateFromEdges(img, "tnut", {}).lines;
}

// A circuit-breaker-like outline of ~1500 pixels: rounded body, two holes, a slot and a lever,
// close to the paper's average template (1,610 points) so CM/OCM/FDCM ratios are comparable.
LineSet breakerTemplate() {
  cv::Mat1b img(200, 280, uchar(0));
  const cv::Rect body(40, 40, 200, 120);
  cv::rectangle(img, body, 255, 1);
  cv::circle(img, {80, 100}, 14, 255, 1);
  cv::circle(img, {200, 100}, 14, 255, 1);
  cv::rectangle(img, cv::Rect(120, 70, 40, 60), 255, 1);
  cv::ellipse(img, {140, 40}, {30, 22}, 0, 180, 360, 255, 1);
  cv::line(img, {20, 80}, {40, 80}, 255);
  cv::line(img, {20, 80}, {20, 120}, 255);
  cv::line(img, {20, 120}, {40, 120}, 255);
  return templateFromEdges(img, "breaker", {}).lines;
}

std::vector<OrientedTemplate> orient(const LineSet& set, int stepChannels) {
  WarpGrid g;
  g.angleStepChannels = stepChannels;
  std::vector<OrientedTemplate> v;
  for (const Warp& w : g.warps(60)) v.push_back(orientTemplate(set, 0, w));
  return v;
}

void report(benchmark::State& state, const SearchResult& r, uint64_t iterations) {
  state.SetItemsProcessed(static_cast<int64_t>(r.stats.hypotheses * iterations));
  state.counters["hypotheses"] = static_cast<double>(r.stats.hypotheses);
  state.counters["evaluated_frac"] = double(r.stats.evaluated) / double(r.stats.hypotheses);
  state.counters["skipped_frac"] = double(r.stats.skipped) / double(r.stats.hypotheses);
  state.counters["lines_per_eval"] = r.stats.evaluated ? double(r.stats.segments) / double(r.stats.evaluated) : 0;
  state.counters["best_cost_px"] = r.candidates.empty() ? -1 : r.candidates[0].cost();
}

}  // namespace

// Line fitting at 640x480 with 1 and 2 threads (the hypotheses' scoring is threaded).
static void BM_LineFit640x480(benchmark::State& state) {
  const Query& q = state.range(0) ? query() : typicalQuery();
  omp_set_num_threads(static_cast<int>(state.range(1)));
  for (auto _ : state) benchmark::DoNotOptimize(fitLines(q.edges));
  omp_set_num_threads(omp_get_num_procs());
  state.counters["edge_pixels"] = q.fit.inputEdgePixels;
  state.counters["lines"] = static_cast<double>(q.fit.set.lines.size());
}
BENCHMARK(BM_LineFit640x480)
    ->ArgsProduct({{0, 1}, {1, 2}})
    ->ArgNames({"dense", "threads"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// DT3 + IDT3 build at 640x480, q = 60, with 1 and 2 threads.
static void BM_Dt3Idt3Build(benchmark::State& state) {
  const Query& q = state.range(1) ? query() : typicalQuery();
  omp_set_num_threads(static_cast<int>(state.range(0)));
  DirectionalDistanceTransform dt3;
  IntegralDistanceTransform idt;
  for (auto _ : state) {
    dt3.compute(q.fit.channelMap, {});
    idt.compute(dt3);
    benchmark::ClobberMemory();
  }
  state.counters["threads"] = static_cast<double>(state.range(0));
  state.counters["dt3_MB"] = dt3.bytes() / 1e6;
  state.counters["idt3_MB"] = idt.bytes() / 1e6;
  state.counters["edge_pixels"] = q.fit.inputEdgePixels;
  state.counters["explained_pixels"] = q.fit.explainedEdgePixels;
  omp_set_num_threads(2);
}
BENCHMARK(BM_Dt3Idt3Build)
    ->ArgsProduct({{1, 2}, {0, 1}})
    ->ArgNames({"threads", "dense"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The same build with oriented channels (edge polarity, docs/fdcm.md): q = 120 over 2 pi, each
// query pixel's channel c or c + 60 (Canny edges have no shadow side, so the polarity is made up:
// alternating 16 px tiles), with no polarity penalty (strict) or the pipeline's 6 px. Compare
// with BM_Dt3Idt3Build of the same threads and density in the same run.
static void BM_Dt3Idt3BuildOriented(benchmark::State& state) {
  const Query& q = state.range(1) ? query() : typicalQuery();
  omp_set_num_threads(static_cast<int>(state.range(0)));
  cv::Mat1b oriented = q.fit.channelMap.clone();
  for (int y = 0; y < oriented.rows; ++y)
    for (int x = 0; x < oriented.cols; ++x)
      if (oriented(y, x) != kNoChannel && (x / 16 + y / 16) % 2)
        oriented(y, x) = static_cast<uchar>(oriented(y, x) + 60);
  Dt3Params p;
  p.q = 120;
  p.oriented = true;
  if (state.range(2)) p.polarityPenalty = 6.0;
  DirectionalDistanceTransform dt3;
  IntegralDistanceTransform idt;
  for (auto _ : state) {
    dt3.compute(oriented, p);
    idt.compute(dt3);
    benchmark::ClobberMemory();
  }
  state.counters["threads"] = static_cast<double>(state.range(0));
  state.counters["dt3_MB"] = dt3.bytes() / 1e6;
  state.counters["idt3_MB"] = idt.bytes() / 1e6;
  omp_set_num_threads(2);
}
BENCHMARK(BM_Dt3Idt3BuildOriented)
    ->ArgsProduct({{1, 2}, {0, 1}, {0, 1}})
    ->ArgNames({"threads", "dense", "penalty"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// Same hypothesis set for every method: a template at 8 rotations (45 degree steps) over every
// translation of the 640x480 query, one thread. range(0): 0 = bounds off (plain exhaustive
// evaluation), 1 = bounds on (each method gets every bound valid for it: CM and FDCM both, OCM
// the hypothesis bound only). range(1): 0 = localisation (best hypothesis), 1 = detection
// (threshold 2.5 px). range(2): 0 = T-nut (small), 1 = breaker (~1500 px).
template <class MakeMatcher>
static void runSearch(benchmark::State& state, MakeMatcher make, int stepChannels) {
  const Query& q = query();
  static const LineSet tnut = tnutTemplate(), breaker = breakerTemplate();
  const auto ts = orient(state.range(2) ? breaker : tnut, stepChannels);
  const auto matcher = make(q);
  SearchParams p;
  p.threads = 1;
  p.hypothesisBound = p.spatialBound = state.range(0) != 0;
  if (state.range(1)) {
    p.mode = SearchMode::Detect;
    p.threshold = 2.5;
  }
  SearchResult r;
  for (auto _ : state) r = exhaustiveSearch(matcher, ts, p);
  report(state, r, state.iterations());
  state.counters["template_pixels"] = ts[0].pixels;
  state.counters["template_lines"] = static_cast<double>(ts[0].segments.size());
}
static void BM_Search_FDCM(benchmark::State& s) {
  runSearch(
      s, [](const Query& q) { return FdcmMatcher(q.idt); }, 15);
}
static void BM_Search_OCM(benchmark::State& s) {
  runSearch(
      s, [](const Query& q) { return ChamferMatcher(q.costs, ChamferMatcher::Kind::OrientedChamfer); }, 15);
}
static void BM_Search_CM(benchmark::State& s) {
  runSearch(
      s, [](const Query& q) { return ChamferMatcher(q.costs, ChamferMatcher::Kind::Chamfer); }, 15);
}
#define SEARCH_ARGS \
  ArgsProduct({{0, 1}, {0, 1}, {0, 1}})->ArgNames({"bounds", "detect", "breaker"})->Unit(benchmark::kMillisecond)
BENCHMARK(BM_Search_FDCM)->SEARCH_ARGS;
BENCHMARK(BM_Search_OCM)->SEARCH_ARGS->Iterations(1);
BENCHMARK(BM_Search_CM)->SEARCH_ARGS->Iterations(1);

// Full in-plane rotation (120 rotations of 3 degrees) over every translation, bounds on, 1 thread.
static void BM_Search_FDCM_FullRotation(benchmark::State& s) {
  runSearch(
      s, [](const Query& q) { return FdcmMatcher(q.idt); }, 1);
}
BENCHMARK(BM_Search_FDCM_FullRotation)
    ->ArgsProduct({{1}, {0, 1}, {0, 1}})
    ->ArgNames({"bounds", "detect", "breaker"})
    ->Unit(benchmark::kMillisecond);

// How far past the threshold a rejected hypothesis is followed so the spatial bound can skip
// (SearchParams::spatialReach, in tenths of a px), breaker template, full rotation, 1 thread.
static void BM_SpatialReach(benchmark::State& state) {
  const Query& q = query();
  static const LineSet breaker = breakerTemplate();
  const auto ts = orient(breaker, 1);
  SearchParams p;
  p.threads = 1;
  p.spatialReach = state.range(0) / 10.0;
  if (state.range(1)) {
    p.mode = SearchMode::Detect;
    p.threshold = 2.5;
  }
  SearchResult r;
  for (auto _ : state) r = exhaustiveSearch(FdcmMatcher(q.idt), ts, p);
  report(state, r, state.iterations());
}
BENCHMARK(BM_SpatialReach)
    ->ArgsProduct({{0, 10, 20, 40, 80, 160, 320}, {0, 1}})
    ->ArgNames({"reach_tenths_px", "detect"})
    ->Unit(benchmark::kMillisecond);

// Fig. 4: evaluated lines vs template points. Curved blobs of growing size; for each, n template
// pixels, m lines, m_hat = lines needed to cover 30 % of the pixels (the paper's measure), and
// the mean lines read per evaluated hypothesis in a detection search with the hypothesis bound.
static void BM_Fig4_LinesVsPoints(benchmark::State& state) {
  const Query& q = query();
  std::mt19937 rng(7);
  const double radius = static_cast<double>(state.range(0));
  double n = 0, m = 0, mhat = 0, perEval = 0;
  const int shapes = 10;
  for (auto _ : state) {
    n = m = mhat = perEval = 0;
    for (int k = 0; k < shapes; ++k) {
      const auto b = blob(rng, radius);
      const int size = static_cast<int>(radius * 3 + 20);
      cv::Mat1b img(size, size, uchar(0));
      std::vector<cv::Point> pts;
      for (auto p : b) pts.emplace_back(cvRound(p.x + size / 2.0), cvRound(p.y + size / 2.0));
      cv::polylines(img, std::vector<std::vector<cv::Point>>{pts}, true, 255, 1);
      const LineSet set = templateFromEdges(img, "blob", {}).lines;
      std::vector<OrientedTemplate> ts{orientTemplate(set, 0, Warp{})};
      const OrientedTemplate& t = ts[0];
      int covered = 0, lines = 0;
      for (const auto& s : t.segments) {
        if (covered >= 0.3 * t.pixels) break;
        covered += s.pixels();
        ++lines;
      }
      SearchParams p;
      p.mode = SearchMode::Detect;
      p.threshold = 2.0;
      p.spatialBound = false;
      p.threads = 1;
      const auto r = exhaustiveSearch(FdcmMatcher(q.idt), ts, p);
      n += t.pixels;
      m += static_cast<double>(t.segments.size());
      mhat += lines;
      perEval += double(r.stats.segments) / double(std::max<uint64_t>(1, r.stats.evaluated));
    }
  }
  state.counters["points_n"] = n / shapes;
  state.counters["lines_m"] = m / shapes;
  state.counters["lines_30pct_mhat"] = mhat / shapes;
  state.counters["mhat_over_n"] = mhat / n;
  state.counters["lines_read_per_hypothesis"] = perEval / shapes;
}
BENCHMARK(BM_Fig4_LinesVsPoints)
    ->Arg(15)
    ->Arg(25)
    ->Arg(40)
    ->Arg(60)
    ->Arg(90)
    ->Arg(130)
    ->Arg(200)
    ->Arg(280)
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
