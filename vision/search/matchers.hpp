#pragma once
// Cost evaluators for the search, one per matching method, with one interface so that every
// comparison runs the same search over the same hypotheses:
//   FdcmMatcher       DCM via IDT3: O(1) per segment (paper Sec. 3.5)
//   ChamferMatcher    CM (Sec. 3.1) and OCM (Shotton et al.), point by point over the template
//   DirectDcmMatcher  DCM summed point by point over DT3 along the same digital lines FDCM uses;
//                     the slow, obviously-right twin of FdcmMatcher (equal to the unit)
//
// Interface used by the search (all costs are integer sums in 1/kCostScale px):
//   struct State;                                       per oriented template, per thread
//   void prepare(const OrientedTemplate&, int txMin, int txMax, State&) const;
//   void beginRow(State&, int ty) const;               translation row ty
//   uint32_t evaluate(const State&, int tx, uint32_t stop, uint64_t& segments) const;
// The search scans translations row by row (tx inner), so consecutive hypotheses read adjacent
// tensor entries.
// evaluate adds segment costs longest first and returns as soon as the sum exceeds `stop` (the
// bound in the hypothesis domain); otherwise it returns the full sum.
#include <algorithm>
#include <cstdint>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "vision/dt3/directional_distance_transform.hpp"
#include "vision/idt3/integral_distance_transform.hpp"
#include "vision/search/oriented_template.hpp"

namespace mfcd::vision {

class FdcmMatcher {
 public:
  explicit FdcmMatcher(const IntegralDistanceTransform& idt) : idt_(idt) {}
  static constexpr bool kLipschitz = true;  // the spatial bound is valid for this cost
  int width() const { return idt_.width(); }
  int height() const { return idt_.height(); }

  struct Item {
    const uint16_t* plane;
    int32_t end0, before0;            // offsets at tx = 0 for the current row
    const int32_t* endFix = nullptr;  // x-major segments: per-tx pattern corrections (x stride)
    const int32_t* beforeFix = nullptr;
  };
  struct State {
    std::vector<Item> items;
    std::vector<int32_t> fixes;
    const OrientedTemplate* t = nullptr;
    int txMin = 0;
  };
  void prepare(const OrientedTemplate& t, int txMin, int txMax, State& s) const;
  void beginRow(State& s, int ty) const;
  uint32_t evaluate(const State& s, int tx, uint32_t stop, uint64_t& segments) const {
    const int k = tx - s.txMin;
    uint32_t sum = 0;
    for (const Item& it : s.items) {
      int32_t e = it.end0 + tx, b = it.before0 + tx;
      if (it.endFix) {
        e += it.endFix[k];
        b += it.beforeFix[k];
      }
      sum += static_cast<uint16_t>(it.plane[e] - it.plane[b]);
      ++segments;
      if (sum > stop) break;
    }
    return sum;
  }

  // The same sum for one translation without prepare()/beginRow(): each segment's two entries
  // are located directly. For searches that visit scattered translations (the 1-D line search),
  // where preparing whole rows would cost more than the evaluations.
  uint32_t evaluateAt(const OrientedTemplate& t, int tx, int ty, uint32_t stop, uint64_t& segments) const {
    return evaluateFrom(t, tx, ty, stop, segments, nullptr, 0);
  }

  // Asks the memory system for the entries the first `count` segments of an evaluateAt() at this
  // translation will read. The search is bound by these reads (IDT3 is tens of MB, far beyond
  // the caches); issued one slide position ahead, they load while the current one is summed.
  // `ends`, when given (room for `count`), receives the entries' addresses for evaluateFrom().
  // Returns how many segments it prefetched.
  size_t prefetchAt(const OrientedTemplate& t, int tx, int ty, size_t count, const uint16_t** ends = nullptr) const {
    count = std::min(count, t.segments.size());
    for (size_t k = 0; k < count; ++k) {
      const auto& seg = t.segments[k];
      const auto e = idt_.ends(seg.channel, seg.x + tx, seg.y + ty, seg.span);
      const uint16_t* plane = idt_.plane(seg.channel);
      prefetch(plane + e.end);
      prefetch(plane + e.before);
      if (ends) ends[2 * k] = plane + e.end, ends[2 * k + 1] = plane + e.before;
    }
    return count;
  }

  // evaluateAt() for the translation a prefetchAt() with `ends` was just issued for: its first
  // `known` segments' entries are read where that found them (locating an entry costs as much
  // as reading it once it is in cache), the rest located directly. The same sum (known = 0 is
  // evaluateAt()).
  uint32_t evaluateFrom(const OrientedTemplate& t, int tx, int ty, uint32_t stop, uint64_t& segments,
                        const uint16_t* const* ends, size_t known) const {
    uint32_t sum = 0;
    for (size_t k = 0; k < known; ++k) {
      sum += static_cast<uint16_t>(*ends[2 * k] - *ends[2 * k + 1]);
      ++segments;
      if (sum > stop) return sum;
    }
    for (size_t k = known; k < t.segments.size(); ++k) {
      const auto& seg = t.segments[k];
      const auto e = idt_.ends(seg.channel, seg.x + tx, seg.y + ty, seg.span);
      const uint16_t* plane = idt_.plane(seg.channel);
      sum += static_cast<uint16_t>(plane[e.end] - plane[e.before]);
      ++segments;
      if (sum > stop) break;
    }
    return sum;
  }

 private:
  // GCC 12 drops __builtin_prefetch here (no instruction is emitted at -O1 and above, measured
  // with -S), so on x86-64 the instruction is written out.
  static void prefetch(const uint16_t* p) {
#if defined(__x86_64__)
    asm volatile("prefetcht0 %0" : : "m"(*p));
#else
    __builtin_prefetch(p);
#endif
  }

  const IntegralDistanceTransform& idt_;
};

// Per-pixel costs of the point-wise baselines, built from the same directional edge map.
struct ChamferCosts {
  cv::Mat1b distance;        // min(maxCost, Euclidean distance to the nearest edge pixel), fixed point
  cv::Mat1b nearestChannel;  // channel of that nearest edge pixel (OCM), kNoChannel without edges
  int q = 0;
  bool oriented = false;  // Dt3Params::oriented
  int lambdaUnits = 0, capUnits = 0;
  void compute(const cv::Mat1b& channelMap, const Dt3Params& params);
};

class ChamferMatcher {
 public:
  enum class Kind { Chamfer, OrientedChamfer };
  ChamferMatcher(const ChamferCosts& costs, Kind kind);
  int width() const { return costs_.distance.cols; }
  int height() const { return costs_.distance.rows; }
  // CM is 1-Lipschitz in translation; OCM's orientation term jumps where the nearest edge
  // changes, so the spatial bound must not be used with it.
  bool lipschitz() const { return kind_ == Kind::Chamfer; }

  struct Segment {
    int begin, end;  // range in offsets
    int channel;
  };
  struct State {
    std::vector<int32_t> offsets;  // template pixels relative to the origin, row-major
    std::vector<Segment> segments;
    int32_t row = 0;
  };
  void prepare(const OrientedTemplate& t, int txMin, int txMax, State& s) const;
  void beginRow(State& s, int ty) const { s.row = ty * costs_.distance.cols; }
  uint32_t evaluate(const State& s, int tx, uint32_t stop, uint64_t& segments) const;

 private:
  const ChamferCosts& costs_;
  Kind kind_;
  DigitalLineTable pattern_;              // each segment's pixels follow its channel's pattern from k = 0
  std::vector<uint8_t> orientationCost_;  // [templateChannel * q + nearestChannel]
};

class DirectDcmMatcher {
 public:
  explicit DirectDcmMatcher(const DirectionalDistanceTransform& dt3);
  static constexpr bool kLipschitz = true;
  int width() const { return dt3_.width(); }
  int height() const { return dt3_.height(); }
  struct State {
    const OrientedTemplate* t = nullptr;
    int ty = 0;
  };
  void prepare(const OrientedTemplate& t, int, int, State& s) const { s.t = &t; }
  void beginRow(State& s, int ty) const { s.ty = ty; }
  uint32_t evaluate(const State& s, int tx, uint32_t stop, uint64_t& segments) const;

 private:
  const DirectionalDistanceTransform& dt3_;
  DigitalLineTable lines_;
};

template <class M>
inline bool matcherIsLipschitz(const M& m) {
  if constexpr (requires { m.lipschitz(); })
    return m.lipschitz();
  else
    return M::kLipschitz;
}

}  // namespace mfcd::vision
