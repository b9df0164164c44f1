#pragma once
// Search over hypotheses (oriented template, tx, ty) with the two bounds of paper Sec. 3.6:
//
// Hypothesis domain: segments are summed longest first and a hypothesis is dropped as soon as its
// partial sum exceeds the threshold (detection) or the current best (localisation).
//
// Spatial domain: DCM is 1-Lipschitz in translation (Eq. 16), so a hypothesis of cost d proves
// that no translation within |delta| < d - tau can reach tau. Two corrections make this exact
// for our discrete costs (docs/fdcm.md derives them): the digital line pattern can move each
// pixel by one more pixel (+1 px) and the 1/8 px rounding of stored costs adds one unit per pixel.
// So a hypothesis with integer sum T over n pixels skips every translation with
//     |delta| < (T - T_tau) / (S n) - 1 - 1/S,      S = kCostScale.
// The hypothesis bound stops a sum right at T_tau, which would leave nothing to skip; with the
// spatial bound on, a sum is followed `spatialReach` px past the threshold so that it can skip.
//
// Both bounds only discard hypotheses that are strictly worse than the threshold or the best, so
// the bounded search returns exactly what the unbounded one does (tests/vision/search).
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <queue>
#include <vector>

#include <omp.h>

#include "vision/search/matchers.hpp"
#include "vision/search/oriented_template.hpp"

namespace mfcd::vision {

enum class SearchMode {
  Best,    // localisation: the single lowest-cost hypothesis (under the threshold, if finite)
  Detect,  // detection: every hypothesis with cost <= threshold (best maxCandidates kept)
};

struct SearchParams {
  SearchMode mode = SearchMode::Best;
  double threshold = std::numeric_limits<double>::infinity();  // tau, px (mean cost per pixel)
  bool hypothesisBound = true;
  bool spatialBound = true;
  double spatialReach = 4.0;  // px followed past tau so that the spatial bound can skip (docs/benchmarks.md)
  size_t maxCandidates = 200000;
  int threads = 0;  // 0: OpenMP default
};

struct Candidate {
  int oriented = -1;  // index into the oriented template list
  int tx = 0, ty = 0;
  uint32_t sum = 0;  // cost sum, 1/kCostScale px units
  int pixels = 1;    // template pixels (normaliser)
  double cost() const { return double(sum) / (double(kCostScale) * pixels); }
};

// Strict total order: lower cost first (compared exactly), then lower (oriented, tx, ty).
inline bool better(const Candidate& a, const Candidate& b) {
  const uint64_t l = uint64_t(a.sum) * uint64_t(b.pixels), r = uint64_t(b.sum) * uint64_t(a.pixels);
  if (l != r) return l < r;
  if (a.oriented != b.oriented) return a.oriented < b.oriented;
  if (a.tx != b.tx) return a.tx < b.tx;
  return a.ty < b.ty;
}

struct SearchStats {
  uint64_t hypotheses = 0;  // size of the hypothesis set (all translations of all oriented templates)
  uint64_t evaluated = 0;   // hypotheses whose cost was (at least partly) computed
  uint64_t skipped = 0;     // hypotheses skipped by the spatial bound
  uint64_t segments = 0;    // segment evaluations (lines read)
  SearchStats& operator+=(const SearchStats& o) {
    hypotheses += o.hypotheses;
    evaluated += o.evaluated;
    skipped += o.skipped;
    segments += o.segments;
    return *this;
  }
};

struct SearchResult {
  std::vector<Candidate> candidates;  // Best: at most one; Detect: sorted by `better`
  SearchStats stats;
  bool truncated = false;  // Detect: more than maxCandidates passed the threshold
};

namespace detail {

inline uint32_t thresholdSum(double tau, int pixels) {
  if (!std::isfinite(tau)) return std::numeric_limits<uint32_t>::max() / 2;
  const double t = std::floor(tau * kCostScale * pixels);
  return t < 0 ? 0 : t > 2e9 ? 2000000000u : static_cast<uint32_t>(t);
}

// Packs the best (sum, pixels) so threads can share it with one atomic word.
inline uint64_t pack(uint32_t sum, uint32_t pixels) { return (uint64_t(sum) << 32) | pixels; }

struct WorstFirst {
  bool operator()(const Candidate& a, const Candidate& b) const { return better(a, b); }
};

}  // namespace detail

template <class Matcher>
SearchResult exhaustiveSearch(const Matcher& matcher, const std::vector<OrientedTemplate>& templates,
                              const SearchParams& params) {
  const int W = matcher.width(), H = matcher.height();
  const bool spatial = params.spatialBound && matcherIsLipschitz(matcher);
  const bool detect = params.mode == SearchMode::Detect;
  std::atomic<uint64_t> best{0};  // pixels == 0: no best yet
  SearchResult result;
  std::vector<std::vector<Candidate>> perThread;
  std::vector<SearchStats> perThreadStats;
  std::vector<uint8_t> overflow;

  const int threads = params.threads > 0 ? params.threads : omp_get_max_threads();
  perThread.resize(threads);
  perThreadStats.resize(threads);
  overflow.assign(threads, 0);

#pragma omp parallel num_threads(threads)
  {
    const int tid = omp_get_thread_num();
    typename Matcher::State state;
    std::vector<int> cover;
    auto& mine = perThread[tid];
    auto& stats = perThreadStats[tid];
    std::priority_queue<Candidate, std::vector<Candidate>, detail::WorstFirst> heap;
    Candidate bestLocal;
    bool haveLocal = false;

#pragma omp for schedule(dynamic, 1)
    for (int o = 0; o < static_cast<int>(templates.size()); ++o) {
      const OrientedTemplate& t = templates[o];
      if (t.pixels <= 0) continue;
      const int txMin = t.txMin(), txMax = t.txMax(W), tyMin = t.tyMin(), tyMax = t.tyMax(H);
      if (txMin > txMax || tyMin > tyMax) continue;
      const int n = t.pixels;
      const uint32_t tauSum = detail::thresholdSum(params.threshold, n);
      const double unitsPerPx = double(kCostScale) * n;
      // Sum beyond the threshold needed before a skip radius becomes positive.
      const double slackSum = double(n) * (kCostScale + 1);
      const uint32_t reach = static_cast<uint32_t>(slackSum + params.spatialReach * unitsPerPx);
      matcher.prepare(t, txMin, txMax, state);
      if (spatial) cover.assign(txMax - txMin + 1, std::numeric_limits<int>::min());
      uint64_t seenBest = ~uint64_t(0);
      uint32_t thr = tauSum;
      for (int ty = tyMin; ty <= tyMax; ++ty) {
        matcher.beginRow(state, ty);
        for (int tx = txMin; tx <= txMax; ++tx) {
          ++stats.hypotheses;
          // cover[column] = last row already proven worse than the threshold in that column.
          if (spatial && cover[tx - txMin] >= ty) {
            ++stats.skipped;
            continue;
          }
          if (!detect) {
            const uint64_t b = best.load(std::memory_order_relaxed);
            if (b != seenBest) {
              seenBest = b;
              const uint32_t bp = static_cast<uint32_t>(b);
              thr = tauSum;
              if (bp) thr = std::min<uint64_t>(thr, (b >> 32) * uint64_t(n) / bp);
            }
          } else if (heap.size() >= params.maxCandidates) {
            const Candidate& w = heap.top();
            thr = std::min<uint32_t>(tauSum, static_cast<uint32_t>(uint64_t(w.sum) * n / w.pixels));
          }
          uint32_t stop = std::numeric_limits<uint32_t>::max();
          if (params.hypothesisBound) {
            const uint64_t s = spatial ? uint64_t(thr) + reach : uint64_t(thr);
            stop = static_cast<uint32_t>(std::min<uint64_t>(s, std::numeric_limits<uint32_t>::max()));
          }
          const uint32_t sum = matcher.evaluate(state, tx, stop, stats.segments);
          ++stats.evaluated;
          if (sum <= thr) {
            const Candidate c{o, tx, ty, sum, n};
            if (detect) {
              if (heap.size() < params.maxCandidates) {
                heap.push(c);
              } else if (better(c, heap.top())) {
                heap.pop();
                heap.push(c);
                overflow[tid] = 1;
              } else {
                overflow[tid] = 1;
              }
            } else if (!haveLocal || better(c, bestLocal)) {
              bestLocal = c;
              haveLocal = true;
              uint64_t cur = best.load();
              const uint64_t mineP = detail::pack(sum, static_cast<uint32_t>(n));
              // Publish if strictly cheaper than the shared best (exact cross-multiplication).
              while (true) {
                const uint32_t cp = static_cast<uint32_t>(cur);
                if (cp && uint64_t(sum) * cp >= (cur >> 32) * uint64_t(n)) break;
                if (best.compare_exchange_weak(cur, mineP)) break;
              }
            }
          }
          if (spatial && sum > thr) {
            // Mark the disc |delta| < r ahead of the scan: rest of this row and the rows below.
            const double r = (double(sum) - double(thr) - slackSum) / unitsPerPx - 1e-9;
            if (r > 0) {
              const double r2 = r * r;
              const int ri = static_cast<int>(std::floor(r));
              const int lo = std::max(txMin, tx - ri), hi = std::min(txMax, tx + ri);
              for (int xx = lo; xx <= hi; ++xx) {
                const double rem = r2 - double(xx - tx) * (xx - tx);
                if (rem <= 0) continue;
                const int dy = static_cast<int>(std::ceil(std::sqrt(rem))) - 1;
                // Rows ty..ty+dy of column xx (row ty only matters for columns ahead of tx,
                // the ones behind are done), contiguous with any earlier cover from row ty on.
                int& c = cover[xx - txMin];
                c = std::max(c, ty + dy);
              }
            }
          }
        }
      }
    }
    if (detect) {
      mine.reserve(heap.size());
      while (!heap.empty()) {
        mine.push_back(heap.top());
        heap.pop();
      }
    } else if (haveLocal) {
      mine.push_back(bestLocal);
    }
  }

  for (int i = 0; i < threads; ++i) {
    result.stats += perThreadStats[i];
    result.candidates.insert(result.candidates.end(), perThread[i].begin(), perThread[i].end());
    result.truncated = result.truncated || overflow[i];
  }
  std::sort(result.candidates.begin(), result.candidates.end(), better);
  if (detect) {
    if (result.candidates.size() > params.maxCandidates) {
      result.candidates.resize(params.maxCandidates);
      result.truncated = true;
    }
  } else if (result.candidates.size() > 1) {
    result.candidates.resize(1);
  }
  return result;
}

}  // namespace mfcd::vision
