#pragma once
// One-dimensional search along major lines (paper Sec. 4.4): under the right alignment a long
// template segment lies on a long query segment. For each oriented template (rotations in whole
// channel steps) and each of its longest segments, and each long query segment of the same
// channel, the template is slid along the query segment, from "template end on query start" to
// "template start on query end", one pixel at a time, and evaluated with FDCM. This reduces the
// 3-DoF (theta, tx, ty) search to 1-DoF searches whose count depends only on line counts.
#include <algorithm>
#include <atomic>
#include <cstdint>
#include <limits>
#include <vector>

#include "vision/search/exhaustive_search.hpp"

namespace mfcd::vision {

struct LineSearchParams {
  int templateLines = 5;  // longest template segments used as guides
  int queryLines = 40;    // longest query segments used as guides
  // Query segments longer than this times the template's longest guide are passed over: at the
  // template's scale none of the part's own edges is that long. The `queryLines` guides are the
  // longest of the rest. Infinity: the longest query segments, whatever the template.
  double maxQueryToGuide = std::numeric_limits<double>::infinity();
  // Only slide positions where the guide and the query segment overlap by at least this
  // fraction of the shorter of the two: under the right alignment one contains most of the
  // other (a fragment of an occluded edge lies inside the template line; a query line that
  // merged collinear edges contains it). 0 slides over every touching position.
  double minOverlap = 0.0;
  // Positions visited along a slide: every `slideStep`-th, then (Best mode) the skipped
  // neighbours of each slide's best. 1 visits all.
  int slideStep = 1;
  SearchMode mode = SearchMode::Best;
  // Best mode: keep the `keep` best hypotheses that lie more than `separationPx` apart (in tx or
  // ty) instead of the single best. In clutter the best placement of a template is often on
  // other parts' edges while the part itself is its second or third; the bound is then the
  // keep-th cost.
  int keep = 1;
  int separationPx = 8;
  double threshold = std::numeric_limits<double>::infinity();
  // Best mode: a bound shared by concurrent searches (SharedCostBound), tightened by the caller
  // as hits come in: a placement costing more can never be used, so it is abandoned early.
  const std::atomic<uint64_t>* sharedBound = nullptr;
  bool hypothesisBound = true;
  size_t maxCandidates = 200000;
};

// A mean cost sum / pixels packed into one atomic word (sum in the high 32 bits), so that
// concurrent searches share a bound without locks. pixels = 0: no bound yet.
struct SharedCostBound {
  static constexpr uint64_t kNone = 0;
  static uint64_t pack(uint32_t sum, uint32_t pixels) { return (uint64_t(sum) << 32) | pixels; }
  // The largest sum over n pixels not above the bound (UINT32_MAX without one).
  static uint32_t sumLimit(uint64_t packed, int n) {
    const uint64_t pixels = packed & 0xffffffffu, sum = packed >> 32;
    if (pixels == 0) return std::numeric_limits<uint32_t>::max();
    return static_cast<uint32_t>(std::min<uint64_t>(sum * uint64_t(n) / pixels, std::numeric_limits<uint32_t>::max()));
  }
  // Lowers the bound to sum / pixels if that is lower (lock-free).
  static void lower(std::atomic<uint64_t>& bound, uint32_t sum, uint32_t pixels) {
    uint64_t cur = bound.load(std::memory_order_relaxed);
    const uint64_t mine = pack(sum, pixels);
    while (true) {
      const uint64_t cp = cur & 0xffffffffu, cs = cur >> 32;
      if (cp != 0 && uint64_t(sum) * cp >= cs * uint64_t(pixels)) return;
      if (bound.compare_exchange_weak(cur, mine, std::memory_order_relaxed)) return;
    }
  }
};

// `queryLines`: the query's fitted segments, longest first (LineFitResult::set.lines).
SearchResult lineSearch(const FdcmMatcher& matcher, const std::vector<OrientedTemplate>& templates,
                        const std::vector<LineSegment>& queryLines, const LineSearchParams& params);
// A search's buffers, kept between calls (one per thread, the pick cycle's use).
// Cache-line aligned: the pipeline keeps one per thread side by side, and these vectors' ends
// change with every template.
struct alignas(64) LineSearchWorkspace {
  struct Slide {
    cv::Point2d start, d;  // translation at k = 0 and its step
    int steps;
  };
  std::vector<Candidate> kept, found;
  std::vector<Slide> slides;
  std::vector<const LineSegment*> guides;
};
// The same search into `out` (replaced), with `ws`: no allocation once both have grown (FDCM;
// the result is the returning form's).
void lineSearch(const FdcmMatcher& matcher, const std::vector<OrientedTemplate>& templates,
                const std::vector<LineSegment>& queryLines, const LineSearchParams& params, LineSearchWorkspace& ws,
                SearchResult& out);
// The same hypotheses scored with CM or OCM (the baselines of the paper's Table 1).
SearchResult lineSearch(const ChamferMatcher& matcher, const std::vector<OrientedTemplate>& templates,
                        const std::vector<LineSegment>& queryLines, const LineSearchParams& params);

}  // namespace mfcd::vision
