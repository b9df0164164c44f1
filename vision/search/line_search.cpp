#include "vision/search/line_search.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace mfcd::vision {

namespace {

// FDCM locates each segment's two IDT3 entries directly for a scattered translation; the
// point-wise baselines use their translation-invariant pixel offsets, prepared once per template.
struct FdcmAt {
  explicit FdcmAt(const FdcmMatcher& matcher) : m(matcher) {}
  const FdcmMatcher& m;
  static constexpr size_t kPrefetchSegments = 16;  // measured: 16 beats 8 (an evaluation reads ~15)
  // The entries the last two prefetches located, and for which translations: a slide prefetches
  // one position ahead, so the visit after the next prefetch is usually at one of them, and then
  // reads them without locating them again.
  struct Located {
    const uint16_t* ends[2 * kPrefetchSegments];
    size_t count = 0;
    int tx = 0, ty = 0;
  };
  Located slot[2]{};
  int newest = 0;
  void prepare(const OrientedTemplate&) { slot[0].count = slot[1].count = 0; }
  uint32_t operator()(const OrientedTemplate& t, int tx, int ty, uint32_t stop, uint64_t& segs) {
    for (Located& l : slot)
      if (l.count > 0 && l.tx == tx && l.ty == ty) return m.evaluateFrom(t, tx, ty, stop, segs, l.ends, l.count);
    return m.evaluateAt(t, tx, ty, stop, segs);
  }
  void prefetch(const OrientedTemplate& t, int tx, int ty) {
    newest ^= 1;
    Located& l = slot[newest];
    l.count = m.prefetchAt(t, tx, ty, kPrefetchSegments, l.ends);
    l.tx = tx;
    l.ty = ty;
  }
};

struct ChamferAt {
  const ChamferMatcher& m;
  ChamferMatcher::State state;
  void prepare(const OrientedTemplate& t) { m.prepare(t, 0, 0, state); }
  uint32_t operator()(const OrientedTemplate&, int tx, int ty, uint32_t stop, uint64_t& segs) {
    m.beginRow(state, ty);
    return m.evaluate(state, tx, stop, segs);
  }
  void prefetch(const OrientedTemplate&, int, int) const {}
};

// Offers c to the kept list (sorted best first, at most `keep`, pairwise more than `sep` px
// apart in tx or ty). A hypothesis at the place of a kept one replaces it only when better.
// Returns whether c was kept.
bool keepBest(std::vector<Candidate>& kept, size_t keep, int sep, const Candidate& c) {
  auto near = [&](const Candidate& k) { return std::abs(k.tx - c.tx) <= sep && std::abs(k.ty - c.ty) <= sep; };
  for (const Candidate& k : kept)
    if (near(k) && !better(c, k)) return false;  // a better one holds this place
  std::erase_if(kept, near);                     // every one here is worse: c takes the place
  if (kept.size() == keep) {
    if (!better(c, kept.back())) return false;
    kept.pop_back();
  }
  kept.insert(std::upper_bound(kept.begin(), kept.end(), c, better), c);
  return true;
}

template <class Matcher, class At>
void lineSearchWith(const Matcher& matcher, At at, const std::vector<OrientedTemplate>& templates,
                    const std::vector<LineSegment>& queryLines, const LineSearchParams& params, LineSearchWorkspace& ws,
                    SearchResult& result) {
  const int W = matcher.width(), H = matcher.height();
  const bool detect = params.mode == SearchMode::Detect;
  result.candidates.clear();
  result.truncated = false;
  // Counted here and stored once at the end: the pipeline's threads keep their results side by
  // side, and a counter written on every hypothesis in a cache line another thread writes too
  // made the whole search up to a third slower, depending on where the allocator put them.
  SearchStats stats;
  const size_t nq = static_cast<size_t>(std::max(0, params.queryLines));
  const size_t keep = static_cast<size_t>(std::max(1, params.keep));
  const int sep = std::max(0, params.separationPx);
  std::vector<Candidate>& kept = ws.kept;  // Best mode: at most `keep`, pairwise more than `sep` apart
  kept.clear();
  kept.reserve(keep);
  std::vector<Candidate>& found = ws.found;
  found.clear();
  using Slide = LineSearchWorkspace::Slide;
  std::vector<Slide>& slides = ws.slides;
  std::vector<const LineSegment*>& guides = ws.guides;
  for (int o = 0; o < static_cast<int>(templates.size()); ++o) {
    const OrientedTemplate& t = templates[o];
    if (t.pixels <= 0 || t.lines.empty()) continue;
    const int txMin = t.txMin(), txMax = t.txMax(W), tyMin = t.tyMin(), tyMax = t.tyMax(H);
    if (txMin > txMax || tyMin > tyMax) continue;
    const int n = t.pixels;
    const uint32_t tauSum = detail::thresholdSum(params.threshold, n);
    // The template's guide segments: its `templateLines` longest transformed source lines, equal
    // lengths in their order (what a stable sort by length then a cut gives, without the sort's
    // temporary buffer: this runs for every warp of every view of every cycle).
    guides.clear();
    const size_t wanted = static_cast<size_t>(std::max(0, params.templateLines));
    for (const auto& l : t.lines) {
      const float len = l.length();
      size_t pos = guides.size();
      while (pos > 0 && guides[pos - 1]->length() < len) --pos;
      if (pos >= wanted) continue;
      guides.insert(guides.begin() + static_cast<std::ptrdiff_t>(pos), &l);
      if (guides.size() > wanted) guides.pop_back();
    }
    at.prepare(t);
    // The query guides: from the first query segment (longest first) the template's longest guide
    // could lie on.
    size_t q0 = 0;
    if (!guides.empty() && std::isfinite(params.maxQueryToGuide)) {
      const double cap = params.maxQueryToGuide * guides.front()->length();
      q0 = static_cast<size_t>(std::partition_point(queryLines.begin(), queryLines.end(),
                                                    [cap](const LineSegment& l) { return l.length() > cap; }) -
                               queryLines.begin());
    }
    const size_t q1 = std::min(queryLines.size(), q0 + nq);
    // The slides: the guide laid on a query segment of the same channel.
    slides.clear();
    for (const LineSegment* g : guides) {
      for (size_t qi = q0; qi < q1; ++qi) {
        const LineSegment& ql = queryLines[qi];
        if (ql.channel != g->channel) continue;
        // Unit direction shared by both segments; order endpoints along it.
        cv::Point2d d(ql.b - ql.a);
        const double qlen = cv::norm(d);
        if (qlen < 1e-6) continue;
        d /= qlen;
        cv::Point2d ta(g->a), tb(g->b);
        if ((tb - ta).dot(d) < 0) std::swap(ta, tb);
        const double tlen = (tb - ta).dot(d);
        // Translation placing template point ta at qa + (k - tlen) * d: the guide covers
        // [k - tlen, k] of the query's [0, qlen], so the overlap is at least m for
        // k in [m, tlen + qlen - m].
        const double m = params.minOverlap * std::min(tlen, qlen);
        const int k0 = static_cast<int>(std::ceil(m)), k1 = static_cast<int>(std::floor(tlen + qlen - m));
        if (k1 < k0) continue;
        slides.push_back(Slide{cv::Point2d(ql.a) - ta + d * (k0 - tlen), d, k1 - k0});
      }
    }
    // The bounds change rarely (a better kept hit, another thread's hit), while a view is visited
    // tens of thousands of times: each is turned into a sum limit for this template's n pixels
    // only when it changes (the divisions cost as much as a segment read).
    uint32_t keptLimit = std::numeric_limits<uint32_t>::max();
    uint64_t sharedSeen = SharedCostBound::kNone;
    uint32_t sharedLimit = std::numeric_limits<uint32_t>::max();
    auto updateKeptLimit = [&] {
      if (!detect && kept.size() == keep) {
        // The bound: the worst kept hypothesis (the only one when keep = 1).
        const Candidate& worst = kept.back();
        keptLimit = static_cast<uint32_t>(std::min<uint64_t>(tauSum, uint64_t(worst.sum) * n / worst.pixels));
      }
    };
    updateKeptLimit();
    // Round half away from zero, as std::lround, without the library call.
    auto roundToInt = [](double x) { return static_cast<int>(x >= 0 ? x + 0.5 : x - 0.5); };
    auto visit = [&](const cv::Point2d& tr) {
      const int tx = roundToInt(tr.x), ty = roundToInt(tr.y);
      if (tx < txMin || tx > txMax || ty < tyMin || ty > tyMax) return false;
      ++stats.hypotheses;
      uint32_t thr = std::min(tauSum, keptLimit);
      if (!detect && params.sharedBound) {
        const uint64_t shared = params.sharedBound->load(std::memory_order_relaxed);
        if (shared != sharedSeen) sharedSeen = shared, sharedLimit = SharedCostBound::sumLimit(shared, n);
        thr = std::min(thr, sharedLimit);
      }
      const uint32_t stop = params.hypothesisBound ? thr : std::numeric_limits<uint32_t>::max();
      const uint32_t sum = at(t, tx, ty, stop, stats.segments);
      ++stats.evaluated;
      if (sum > thr) return false;
      const Candidate c{o, tx, ty, sum, n};
      if (detect) {
        found.push_back(c);
        return false;
      }
      const bool keptIt = keepBest(kept, keep, sep, c);
      if (keptIt) updateKeptLimit();
      return keptIt;
    };
    const int step = std::max(1, params.slideStep);
    for (const Slide& sl : slides) {
      // Unit steps along a slide rarely round to the same pixel twice, and a translation shared
      // by two slides is simply evaluated twice (cheaper than remembering every translation;
      // NMS merges duplicates). With a coarser step, the best position of the slide is then
      // refined by visiting its skipped neighbours.
      int improvedAt = -1;
      for (int k = 0; k <= sl.steps; k += step) {
        if (k + step <= sl.steps) {
          const cv::Point2d next = sl.start + sl.d * (k + step);
          const int nx = roundToInt(next.x), ny = roundToInt(next.y);
          if (nx >= txMin && nx <= txMax && ny >= tyMin && ny <= tyMax) at.prefetch(t, nx, ny);
        }
        if (visit(sl.start + sl.d * k)) improvedAt = k;
      }
      if (improvedAt >= 0 && step > 1)
        for (int dk = 1; dk < step; ++dk) {
          if (improvedAt - dk >= 0) visit(sl.start + sl.d * (improvedAt - dk));
          if (improvedAt + dk <= sl.steps) visit(sl.start + sl.d * (improvedAt + dk));
        }
    }
  }
  result.stats = stats;
  if (detect) {
    std::sort(found.begin(), found.end(), better);
    if (found.size() > params.maxCandidates) {
      found.resize(params.maxCandidates);
      result.truncated = true;
    }
    result.candidates.assign(found.begin(), found.end());
  } else {
    result.candidates.assign(kept.begin(), kept.end());
  }
}

}  // namespace

SearchResult lineSearch(const FdcmMatcher& matcher, const std::vector<OrientedTemplate>& templates,
                        const std::vector<LineSegment>& queryLines, const LineSearchParams& params) {
  LineSearchWorkspace ws;
  SearchResult result;
  lineSearchWith(matcher, FdcmAt{matcher}, templates, queryLines, params, ws, result);
  return result;
}

void lineSearch(const FdcmMatcher& matcher, const std::vector<OrientedTemplate>& templates,
                const std::vector<LineSegment>& queryLines, const LineSearchParams& params, LineSearchWorkspace& ws,
                SearchResult& out) {
  lineSearchWith(matcher, FdcmAt{matcher}, templates, queryLines, params, ws, out);
}

SearchResult lineSearch(const ChamferMatcher& matcher, const std::vector<OrientedTemplate>& templates,
                        const std::vector<LineSegment>& queryLines, const LineSearchParams& params) {
  LineSearchWorkspace ws;
  SearchResult result;
  lineSearchWith(matcher, ChamferAt{matcher, {}}, templates, queryLines, params, ws, result);
  return result;
}

}  // namespace mfcd::vision
