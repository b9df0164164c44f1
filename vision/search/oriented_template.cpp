#include "vision/search/oriented_template.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace mfcd::vision {

cv::Matx22d Warp::matrix() const {
  const double c = std::cos(angle), s = std::sin(angle);
  return cv::Matx22d(c, -s, s, c) * cv::Matx22d(scale * aspect, 0, 0, scale);
}

OrientedTemplate orientTemplate(const LineSet& set, int templateIndex, const Warp& warp) {
  OrientedTemplate t;
  std::vector<DigitalSegment> scratch;
  orientTemplate(set, templateIndex, warp, t, scratch);
  return t;
}

void orientTemplate(const LineSet& set, int templateIndex, const Warp& warp, OrientedTemplate& t,
                    std::vector<DigitalSegment>& scratch) {
  const OrientationChannels ch(set.q, set.oriented);
  const cv::Matx22d A = warp.matrix();
  t.templateIndex = templateIndex;
  t.warp = warp;
  t.segments.clear();
  t.lines.clear();
  t.pixels = 0;
  t.x0 = t.y0 = t.x1 = t.y1 = 0;
  bool first = true;
  for (const auto& l : set.lines) {
    const cv::Vec2d a = A * cv::Vec2d(l.a.x - set.origin.x, l.a.y - set.origin.y);
    const cv::Vec2d b = A * cv::Vec2d(l.b.x - set.origin.x, l.b.y - set.origin.y);
    const cv::Vec2d dv = b - a;
    if (cv::norm(dv) < 1.0) continue;
    const int c = ch.channelOf(std::atan2(dv[1], dv[0]));
    const bool xm = ch.xMajor(c);
    const double am = xm ? a[0] : a[1], bm = xm ? b[0] : b[1];
    const cv::Vec2d s = am <= bm ? a : b;
    const double extent = std::abs(bm - am);
    const int span = static_cast<int>(std::lround(extent));
    LineSegment tl;
    tl.a = cv::Point2f(static_cast<float>(a[0]), static_cast<float>(a[1]));
    tl.b = cv::Point2f(static_cast<float>(b[0]), static_cast<float>(b[1]));
    tl.channel = c;
    tl.support = span + 1;
    t.lines.push_back(tl);
    // Digital pixels follow the channel's slope; the true line may differ by up to half a
    // channel. Pieces restart on the true line often enough that no pixel drifts more than
    // kMaxDrift from it, and are short enough for exact 16-bit IDT3 sums.
    const double slope = ch.minorSlope(c);
    const cv::Vec2d forward = am <= bm ? dv : cv::Vec2d(-dv);  // from the start s to the other end
    const cv::Vec2d unitMajor = forward / std::max(1e-12, std::abs(xm ? dv[0] : dv[1]));  // 1 major step
    const double trueSlope = xm ? unitMajor[1] : unitMajor[0];
    const double drift = std::abs(trueSlope - slope);
    constexpr double kMaxDrift = 0.5;
    const int maxPixels = drift * kMaxSegmentSpan > kMaxDrift
                              ? std::max(1, static_cast<int>(std::floor(kMaxDrift / drift)) + 1)
                              : kMaxSegmentSpan + 1;
    const int pieces = (span + 1 + maxPixels - 1) / maxPixels;
    for (int j = 0; j < pieces; ++j) {
      const int o0 = static_cast<int>(static_cast<long>(j) * (span + 1) / pieces);
      const int o1 = static_cast<int>(static_cast<long>(j + 1) * (span + 1) / pieces) - 1;
      const cv::Vec2d ps = s + unitMajor * o0;
      DigitalSegment seg;
      seg.channel = static_cast<uint8_t>(c);
      seg.span = static_cast<uint8_t>(o1 - o0);
      seg.x = static_cast<int16_t>(std::lround(ps[0]));
      seg.y = static_cast<int16_t>(std::lround(ps[1]));
      t.segments.push_back(seg);
      t.pixels += seg.pixels();
      // Pixels run from the start along the major axis; the minor coordinate follows the slope
      // within +-1 (pattern anchoring), hence the margin of one pixel on both minor sides.
      const int spanMinor = static_cast<int>(std::floor(seg.span * slope + 0.5));
      int ax0, ax1, ay0, ay1;
      if (xm) {
        ax0 = seg.x;
        ax1 = seg.x + seg.span;
        ay0 = seg.y + std::min(0, spanMinor) - 1;
        ay1 = seg.y + std::max(0, spanMinor) + 1;
      } else {
        ay0 = seg.y;
        ay1 = seg.y + seg.span;
        ax0 = seg.x + std::min(0, spanMinor) - 1;
        ax1 = seg.x + std::max(0, spanMinor) + 1;
      }
      if (first) {
        t.x0 = ax0;
        t.x1 = ax1;
        t.y0 = ay0;
        t.y1 = ay1;
        first = false;
      } else {
        t.x0 = std::min(t.x0, ax0);
        t.x1 = std::max(t.x1, ax1);
        t.y0 = std::min(t.y0, ay0);
        t.y1 = std::max(t.y1, ay1);
      }
    }
  }
  // Most pixels first, equal spans in digitising order (a stable sort): a counting sort by span,
  // which needs no buffer beyond `scratch` (std::stable_sort allocates one).
  std::array<int, 257> start{};
  for (const DigitalSegment& seg : t.segments) ++start[255 - seg.span + 1];
  for (size_t k = 1; k < start.size(); ++k) start[k] += start[k - 1];
  scratch.resize(t.segments.size());
  for (const DigitalSegment& seg : t.segments) scratch[static_cast<size_t>(start[255 - seg.span]++)] = seg;
  t.segments.assign(scratch.begin(), scratch.end());
}

void reserveOrientedTemplate(const LineSet& set, double max_stretch, OrientedTemplate& out,
                             std::vector<DigitalSegment>& scratch) {
  // A line's major extent is at most its warped length, so it gives at most span + 1 pieces of
  // one pixel or more.
  size_t segments = 0;
  for (const auto& l : set.lines) segments += static_cast<size_t>(std::lround(l.length() * max_stretch)) + 1;
  out.lines.reserve(set.lines.size());
  out.segments.reserve(segments);
  scratch.reserve(segments);
}

std::vector<double> WarpGrid::series(double centre, double ratio, int count) {
  if (count <= 0 || ratio <= 0) throw std::invalid_argument("warp grid: series needs count >= 1 and ratio > 0");
  std::vector<double> v;
  for (int i = 0; i < count; ++i) v.push_back(centre * std::pow(ratio, i - (count - 1) / 2.0));
  return v;
}

std::vector<Warp> WarpGrid::warps(int q, bool oriented) const {
  if (angleStepChannels <= 0) throw std::invalid_argument("warp grid: angleStepChannels must be >= 1");
  if (scales.empty() || aspects.empty()) throw std::invalid_argument("warp grid: needs at least one scale and aspect");
  for (double s : scales)
    if (!(s > 0.05 && s < 20)) throw std::invalid_argument("warp grid: scale out of range (0.05, 20)");
  for (double a : aspects)
    if (!(a > 0.2 && a < 5)) throw std::invalid_argument("warp grid: aspect out of range (0.2, 5)");
  const double step = OrientationChannels(q, oriented).step() * angleStepChannels;
  std::vector<Warp> out;
  const int first = static_cast<int>(std::ceil(angleMin / step - 1e-9));
  for (int r = first; r * step < angleMax - 1e-9; ++r)
    for (double s : scales)
      for (double a : aspects) out.push_back({r * step, s, a});
  return out;
}

}  // namespace mfcd::vision
