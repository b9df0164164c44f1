#include "vision/search/matchers.hpp"

#include <algorithm>
#include <cmath>

#include "vision/common/euclidean_dt.hpp"

namespace mfcd::vision {

void FdcmMatcher::prepare(const OrientedTemplate& t, int txMin, int txMax, State& s) const {
  s.t = &t;
  s.txMin = txMin;
  s.items.assign(t.segments.size(), Item{});
  const int cols = std::max(0, txMax - txMin + 1);
  const int st = idt_.stride();
  size_t xMajor = 0;
  for (const auto& seg : t.segments) xMajor += idt_.lines().xMajor(seg.channel) ? 1 : 0;
  s.fixes.assign(xMajor * 2 * cols, 0);
  size_t f = 0;
  for (size_t i = 0; i < t.segments.size(); ++i) {
    const auto& seg = t.segments[i];
    s.items[i].plane = idt_.plane(seg.channel);
    if (!idt_.lines().xMajor(seg.channel)) continue;
    // For x-major segments the pattern is indexed by the column, so the end rows depend on tx
    // beyond the plain column shift: store the row difference (times the stride) per tx.
    int32_t* ef = s.fixes.data() + f;
    int32_t* bf = ef + cols;
    f += 2 * cols;
    const int16_t* m = idt_.lines().minor(seg.channel);
    for (int k = 0; k < cols; ++k) {
      const int X = seg.x + txMin + k + 1;
      ef[k] = (m[X + seg.span] - m[X]) * st;
      bf[k] = -(m[X] - m[X - 1]) * st;
    }
    s.items[i].endFix = ef;
    s.items[i].beforeFix = bf;
  }
}

void FdcmMatcher::beginRow(State& s, int ty) const {
  const int st = idt_.stride();
  for (size_t i = 0; i < s.items.size(); ++i) {
    const auto& seg = s.t->segments[i];
    Item& it = s.items[i];
    if (!it.endFix) {
      const auto e = idt_.ends(seg.channel, seg.x, seg.y + ty, seg.span);
      it.end0 = e.end;
      it.before0 = e.before;
    } else {
      const int Y = seg.y + ty + 1;
      it.end0 = Y * st + seg.x + 1 + seg.span;
      it.before0 = Y * st + seg.x;
    }
  }
}

void ChamferCosts::compute(const cv::Mat1b& channelMap, const Dt3Params& params) {
  params.validate();
  q = params.q;
  oriented = params.oriented;
  lambdaUnits = params.lambdaUnits();
  capUnits = params.capUnits();
  cv::Mat1b sites = channelMap != kNoChannel;
  cv::Mat1i d2, nearest;
  squaredEuclideanDistance(sites, d2, &nearest);
  distance.create(channelMap.size());
  nearestChannel.create(channelMap.size());
  for (int y = 0; y < channelMap.rows; ++y)
    for (int x = 0; x < channelMap.cols; ++x) {
      const int n = nearest(y, x);
      const double d = n == kNoSite ? 1e9 : std::sqrt(double(d2(y, x)));
      distance(y, x) = static_cast<uchar>(std::min<long>(capUnits, std::lround(d * kCostScale)));
      nearestChannel(y, x) = n == kNoSite ? kNoChannel : channelMap(n / channelMap.cols, n % channelMap.cols);
    }
}

ChamferMatcher::ChamferMatcher(const ChamferCosts& costs, Kind kind)
    : costs_(costs),
      kind_(kind),
      pattern_(OrientationChannels(costs.q, costs.oriented), kMaxSegmentSpan + 1, kMaxSegmentSpan + 1) {
  const int q = costs.q;
  const OrientationChannels ch(q, costs.oriented);
  orientationCost_.assign(static_cast<size_t>(q) * 256, 0);
  for (int a = 0; a < q; ++a)
    for (int b = 0; b < 256; ++b)
      orientationCost_[a * 256 + b] =
          static_cast<uint8_t>(std::min(255, b < q ? costs.lambdaUnits * ch.distance(a, b) : costs.capUnits));
}

void ChamferMatcher::prepare(const OrientedTemplate& t, int, int, State& s) const {
  // CM and OCM use the template as a fixed point set: each segment's pixels follow the line
  // pattern anchored at the segment's own start, so the set is translation invariant.
  const int w = costs_.distance.cols;
  s.offsets.clear();
  s.segments.clear();
  for (const auto& seg : t.segments) {
    const bool xm = pattern_.xMajor(seg.channel);
    const int16_t* m = pattern_.minor(seg.channel);  // m[0] = 0: anchored at the segment start
    Segment rs{static_cast<int>(s.offsets.size()), 0, seg.channel};
    for (int k = 0; k <= seg.span; ++k) {
      const int minor = m[k];
      const int x = xm ? seg.x + k : seg.x + minor, y = xm ? seg.y + minor : seg.y + k;
      s.offsets.push_back(y * w + x);
    }
    rs.end = static_cast<int>(s.offsets.size());
    s.segments.push_back(rs);
  }
}

uint32_t ChamferMatcher::evaluate(const State& s, int tx, uint32_t stop, uint64_t& segments) const {
  const int32_t base = s.row + tx;
  const uint8_t* dist = costs_.distance.ptr<uint8_t>(0) + base;
  uint32_t sum = 0;
  if (kind_ == Kind::Chamfer) {
    for (const auto& seg : s.segments) {
      for (int i = seg.begin; i < seg.end; ++i) sum += dist[s.offsets[i]];
      ++segments;
      if (sum > stop) break;
    }
  } else {
    const uint8_t* nn = costs_.nearestChannel.ptr<uint8_t>(0) + base;
    const int cap = costs_.capUnits;
    for (const auto& seg : s.segments) {
      const uint8_t* oc = orientationCost_.data() + seg.channel * 256;
      for (int i = seg.begin; i < seg.end; ++i) {
        const int o = s.offsets[i];
        sum += static_cast<uint32_t>(std::min(cap, dist[o] + oc[nn[o]]));
      }
      ++segments;
      if (sum > stop) break;
    }
  }
  return sum;
}

DirectDcmMatcher::DirectDcmMatcher(const DirectionalDistanceTransform& dt3)
    : dt3_(dt3), lines_(dt3.channels(), dt3.width() + 2, dt3.height() + 2) {}

uint32_t DirectDcmMatcher::evaluate(const State& s, int tx, uint32_t stop, uint64_t& segments) const {
  uint32_t sum = 0;
  for (const auto& seg : s.t->segments) {
    forEachPixel(lines_, seg.channel, seg.x + tx, seg.y + s.ty, seg.span, 1,
                 [&](int x, int y) { sum += dt3_.at(seg.channel, x, y); });
    ++segments;
    if (sum > stop) break;
  }
  return sum;
}

}  // namespace mfcd::vision
