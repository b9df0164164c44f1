#include "vision/lines/line_fitter.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace mfcd::vision {

void LineFitParams::validate() const {
  if (q <= 0 || q > kMaxChannels) throw std::invalid_argument("line fitting: q must be in 1..180");
  if (!(residual > 0 && residual <= 5)) throw std::invalid_argument("line fitting: residual must be in (0, 5] px");
  if (maxGap < 0 || maxGap > 50) throw std::invalid_argument("line fitting: maxGap must be in 0..50 px");
  if (minSupport < 2) throw std::invalid_argument("line fitting: minSupport must be >= 2");
  if (directionRadius < 1 || directionRadius > 10)
    throw std::invalid_argument("line fitting: directionRadius must be in 1..10");
  if (channelSpread < 0 || channelSpread > q / 4)
    throw std::invalid_argument("line fitting: channelSpread must be in 0..q/4");
  if (refineIterations < 0 || refineIterations > 10)
    throw std::invalid_argument("line fitting: refineIterations must be in 0..10");
  if (oriented && 2 * q > kMaxChannels)
    throw std::invalid_argument("line fitting: oriented lines have 2q channels, at most " +
                                std::to_string(kMaxChannels));
}

namespace {

class Tracer {
 public:
  Tracer(const cv::Mat1b& alive, const LineFitParams& p) : alive_(alive), p_(p) {}

  // Walks the line of direction `phi` through `origin` in both directions and collects alive pixels
  // within the residual band, as long as gaps stay <= maxGap. Returns the support count; when
  // `out` is given, appends the support pixels.
  int trace(cv::Point2d origin, double phi, std::vector<cv::Point>* out) const {
    return trace(origin, TraceDirection(phi, p_.residual), out);
  }
  int trace(cv::Point2d origin, const TraceDirection& walk, std::vector<cv::Point>* out) const {
    const bool xm = walk.xm;
    const double slope = walk.slope;
    const double major0 = xm ? origin.x : origin.y;
    const double minor0 = xm ? origin.y : origin.x;
    const double band = walk.band;
    const int majorLimit = xm ? alive_.cols : alive_.rows;
    const int minorLimit = xm ? alive_.rows : alive_.cols;
    int count = 0;
    const int start = static_cast<int>(std::lround(major0));
    for (int dir = +1; dir >= -1; dir -= 2) {
      int gap = 0;
      for (int k = dir > 0 ? start : start - 1; k >= 0 && k < majorLimit; k += dir) {
        const double mid = minor0 + slope * (k - major0);
        const int lo = std::max(0, static_cast<int>(std::ceil(mid - band)));
        const int hi = std::min(minorLimit - 1, static_cast<int>(std::floor(mid + band)));
        int here = 0;
        for (int m = lo; m <= hi; ++m) {
          const int x = xm ? k : m, y = xm ? m : k;
          if (alive_(y, x)) {
            ++here;
            if (out) out->emplace_back(x, y);
          }
        }
        if (here) {
          count += here;
          gap = 0;
        } else if (++gap > p_.maxGap) {
          break;
        }
      }
    }
    return count;
  }

 private:
  const cv::Mat1b& alive_;
  const LineFitParams& p_;
};

// Local tangent angle of each edge pixel from the principal axis of its edge neighbours.
std::vector<float> localDirections(const std::vector<cv::Point>& pts, const cv::Mat1b& edges, int r) {
  std::vector<float> dir(pts.size(), 0.f);
  for (size_t i = 0; i < pts.size(); ++i) {
    double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
    int n = 0;
    for (int dy = -r; dy <= r; ++dy) {
      const int y = pts[i].y + dy;
      if (y < 0 || y >= edges.rows) continue;
      for (int dx = -r; dx <= r; ++dx) {
        const int x = pts[i].x + dx;
        if (x < 0 || x >= edges.cols || !edges(y, x)) continue;
        sx += dx;
        sy += dy;
        sxx += dx * dx;
        syy += dy * dy;
        sxy += dx * dy;
        ++n;
      }
    }
    if (n < 2) continue;
    const double cxx = sxx / n - (sx / n) * (sx / n);
    const double cyy = syy / n - (sy / n) * (sy / n);
    const double cxy = sxy / n - (sx / n) * (sy / n);
    dir[i] = static_cast<float>(0.5 * std::atan2(2 * cxy, cxx - cyy));
  }
  return dir;
}

}  // namespace

LineFitResult fitLines(const cv::Mat1b& edges, const LineFitParams& params, const cv::Mat1f* direction,
                       const cv::Mat1f* shadow) {
  LineFitter fitter(params);
  LineFitResult result;
  fitter.fit(edges, direction, result, shadow);
  return result;
}

LineFitter::LineFitter(const LineFitParams& params) : params_(params) {
  params_.validate();
  // Every channel's walk, once: the seeds' hypotheses all lie on channel directions.
  const OrientationChannels ch(params_.q);
  for (int c = 0; c < params_.q; ++c) walks_.emplace_back(ch.angleOf(c), params_.residual);
}

void LineFitter::fit(const cv::Mat1b& edges, const cv::Mat1f* direction, LineFitResult& result,
                     const cv::Mat1f* shadow) {
  const LineFitParams& params = params_;
  if (edges.empty()) throw std::invalid_argument("line fitting: empty edge image");
  if (direction && direction->size() != edges.size())
    throw std::invalid_argument("line fitting: direction map size differs from the edge map");
  if (params.oriented && !shadow) throw std::invalid_argument("line fitting: oriented lines need the shadow map");
  if (params.oriented && shadow->size() != edges.size())
    throw std::invalid_argument("line fitting: shadow map size differs from the edge map");
  const OrientationChannels ch(params.q);

  result.set.q = params.oriented ? 2 * params.q : params.q;
  result.set.oriented = params.oriented;
  result.set.size = edges.size();
  result.set.origin = cv::Point2f(edges.cols / 2.0f, edges.rows / 2.0f);
  result.set.lines.clear();
  result.inputEdgePixels = 0;
  result.explainedEdgePixels = 0;
  // Filled by hand: Mat::setTo allocates (OpenCV's scalar conversion) and this runs every cycle.
  // create() keeps the storage of a map of this size, which is continuous.
  if (!result.channelMap.isContinuous()) result.channelMap.release();
  result.channelMap.create(edges.size());
  std::fill_n(result.channelMap.ptr<uchar>(), result.channelMap.total(), kNoChannel);

  std::vector<cv::Point>& pts = pts_;
  pts.clear();
  alive_.create(edges.size());
  std::fill_n(alive_.ptr<uchar>(), alive_.total(), uchar(0));
  cv::Mat1b& alive = alive_;
  for (int y = 0; y < edges.rows; ++y)
    for (int x = 0; x < edges.cols; ++x)
      if (edges(y, x)) {
        pts.emplace_back(x, y);
        alive(y, x) = 1;
      }
  result.inputEdgePixels = static_cast<int>(pts.size());
  if (pts.empty()) return;

  std::vector<float>& dir = dir_;
  if (direction) {
    dir.resize(pts.size());
    for (size_t i = 0; i < pts.size(); ++i) dir[i] = (*direction)(pts[i]);
  } else {
    dir = localDirections(pts, edges, params.directionRadius);
  }

  const Tracer tracer(alive, params);
  const std::vector<TraceDirection>& walks = walks_;
  // Every seed's hypotheses are scored on the untouched edge map, so independently: shared out
  // among the threads (more than half of the stage's time before). Hypothesis's order is total
  // (score, then seed, then channel), so the queue pops them in the same order however it was
  // built, and the result is the one-thread result.
  const int spread = params.channelSpread, per_seed = 2 * spread + 1;
  const int n = static_cast<int>(pts.size());
  std::vector<int>& scores = seed_scores_;
  scores.resize(pts.size() * static_cast<size_t>(per_seed));
#pragma omp parallel for schedule(static)
  for (int i = 0; i < n; ++i) {
    const int c0 = ch.channelOf(dir[i]);
    for (int s = -spread; s <= spread; ++s)
      scores[static_cast<size_t>(i) * per_seed + (s + spread)] =
          tracer.trace(cv::Point2d(pts[i]), walks[static_cast<size_t>(ch.wrap(c0 + s))], nullptr);
  }
  HypothesisQueue& queue = queue_;
  // A support is at most the pixels of one band across the image: scores stay below this.
  const int longest = std::max(edges.cols, edges.rows);
  queue.reset(longest * (2 * static_cast<int>(std::ceil(params.residual * std::sqrt(2.0))) + 1));
  for (int i = 0; i < n; ++i) {
    const int c0 = ch.channelOf(dir[i]);
    for (int s = -spread; s <= spread; ++s) {
      const int score = scores[static_cast<size_t>(i) * per_seed + (s + spread)];
      if (score >= params.minSupport) queue.add({score, i, ch.wrap(c0 + s)});
    }
  }
  queue.build();

  std::vector<cv::Point>& support = support_;
  while (!queue.empty()) {
    Hypothesis h = queue.pop();
    // Lazy greedy: supports only shrink as points are claimed, so a re-scored hypothesis that
    // still beats every stored (optimistic) score is the true best.
    h.score = tracer.trace(cv::Point2d(pts[h.seed]), walks[static_cast<size_t>(h.channel)], nullptr);
    if (h.score < params.minSupport) continue;
    if (!queue.empty() && h.score < queue.top_score()) {
      queue.push(h);
      continue;
    }
    // Accept, then refine: the channel direction only found the group of points; the segment
    // itself is the total-least-squares line of its support (free direction), re-traced so that
    // it reaches the true ends of an edge lying between two channel directions.
    double phi = ch.angleOf(h.channel);
    cv::Point2d p0(pts[h.seed]);
    support.clear();
    tracer.trace(p0, walks[static_cast<size_t>(h.channel)], &support);
    for (int it = 0; it < params.refineIterations && static_cast<int>(support.size()) >= 2; ++it) {
      cv::Point2d mean(0, 0);
      for (const auto& sp : support) mean += cv::Point2d(sp);
      mean /= static_cast<double>(support.size());
      double cxx = 0, cyy = 0, cxy = 0;
      for (const auto& sp : support) {
        const cv::Point2d d = cv::Point2d(sp) - mean;
        cxx += d.x * d.x;
        cyy += d.y * d.y;
        cxy += d.x * d.y;
      }
      const double fitted = 0.5 * std::atan2(2 * cxy, cxx - cyy);
      // Keep the hypothesis direction if the support is too short to define one.
      if (std::abs(std::remainder(fitted - phi, CV_PI)) <= ch.step()) phi = fitted;
      p0 = mean;
      std::vector<cv::Point>& next = next_;
      next.clear();
      tracer.trace(p0, phi, &next);
      if (next.size() < support.size()) break;  // refinement must not lose support
      support.swap(next);
    }
    const cv::Point2d d(std::cos(phi), std::sin(phi)), nrm(-std::sin(phi), std::cos(phi));
    // Near a corner the neighbouring edge stays inside the band for a few pixels; trim ends whose
    // residual is beyond what a digitised straight line produces, so segments stop at corners.
    std::sort(support.begin(), support.end(), [&](const cv::Point& u, const cv::Point& v) {
      return (cv::Point2d(u) - p0).dot(d) < (cv::Point2d(v) - p0).dot(d);
    });
    const double trim = std::min(params.residual, 0.75);
    size_t lo = 0, hi = support.size();
    while (hi - lo > 0 && std::abs((cv::Point2d(support[lo]) - p0).dot(nrm)) > trim) ++lo;
    while (hi - lo > 0 && std::abs((cv::Point2d(support[hi - 1]) - p0).dot(nrm)) > trim) --hi;
    if (static_cast<int>(hi - lo) < params.minSupport) continue;
    const double tmin = (cv::Point2d(support[lo]) - p0).dot(d);
    const double tmax = (cv::Point2d(support[hi - 1]) - p0).dot(d);
    LineSegment seg;
    seg.a = cv::Point2f(p0 + d * tmin);
    seg.b = cv::Point2f(p0 + d * tmax);
    seg.channel = ch.channelOf(phi);
    seg.support = static_cast<int>(hi - lo);
    if (params.oriented) {
      // The majority of the support's shadow normals says which side of the line is the shadow.
      // Oriented channel c (the same direction) or c + q (reversed), decided against the
      // channel's centre so that it is always the undirected channel modulo q.
      // A pixel votes for phi when its shadow normal lies on the left of phi's direction.
      int votes = 0;
      for (size_t i = lo; i < hi; ++i) votes += shadow_left_of(phi, (*shadow)(support[i])) ? 1 : -1;
      const bool reversed = votes < 0;
      if (reversed) std::swap(seg.a, seg.b);
      const double oriented = reversed ? phi + CV_PI : phi;
      const double centre = ch.angleOf(seg.channel);
      seg.channel += std::cos(oriented - centre) >= 0 ? 0 : params.q;
    }
    for (size_t i = lo; i < hi; ++i) {
      alive(support[i]) = 0;
      result.channelMap(support[i]) = static_cast<uchar>(seg.channel);
    }
    result.explainedEdgePixels += seg.support;
    result.set.lines.push_back(seg);
  }
  sortLongestFirst(result.set.lines, order_, sorted_);
}

void HypothesisQueue::reset(int max_score) {
  heads_.assign(static_cast<size_t>(std::max(max_score, 0)) + 1, -1);  // within capacity: no allocation
  pool_.clear();
  free_.clear();
  order_.clear();
  top_ = -1;
}

void HypothesisQueue::link(int score, const Key& key) {
  if (score < 0) throw std::invalid_argument("HypothesisQueue: negative score");
  if (static_cast<size_t>(score) >= heads_.size()) heads_.resize(static_cast<size_t>(score) + 1, -1);
  int slot;
  if (!free_.empty()) {
    slot = free_.back();
    free_.pop_back();
    pool_[static_cast<size_t>(slot)] = {key, heads_[static_cast<size_t>(score)]};
  } else {
    slot = static_cast<int>(pool_.size());
    pool_.push_back({key, heads_[static_cast<size_t>(score)]});
  }
  heads_[static_cast<size_t>(score)] = slot;
}

void HypothesisQueue::add(const LineHypothesis& h) {
  link(h.score, {h.seed, h.channel});
  top_ = std::max(top_, h.score);
}

void HypothesisQueue::collect_top() {
  order_.clear();
  if (top_ < 0) return;
  int& head = heads_[static_cast<size_t>(top_)];
  for (int i = head; i >= 0; i = pool_[static_cast<size_t>(i)].next) {
    order_.push_back(pool_[static_cast<size_t>(i)].key);
    free_.push_back(i);
  }
  head = -1;
  std::sort(order_.begin(), order_.end());
}

void HypothesisQueue::build() {
  // Room for every entry's slot to come back free, and for the largest score's list.
  free_.reserve(pool_.size());
  order_.reserve(pool_.size());
  collect_top();
}

void HypothesisQueue::push(const LineHypothesis& h) {
  if (h.score >= top_) throw std::invalid_argument("HypothesisQueue: push at or above the top score");
  link(h.score, {h.seed, h.channel});
}

LineHypothesis HypothesisQueue::pop() {
  if (top_ < 0) throw std::logic_error("HypothesisQueue: pop from an empty queue");
  const Key k = order_.back();
  order_.pop_back();
  const LineHypothesis h{top_, k.seed, k.channel};
  if (order_.empty()) {
    do --top_;
    while (top_ >= 0 && heads_[static_cast<size_t>(top_)] < 0);
    collect_top();
  }
  return h;
}

void reduceQuery(const LineSet& lines, const cv::Mat1b& channelMap, int factor, LineSet& reducedLines,
                 cv::Mat1b& reducedMap) {
  if (factor < 1) throw std::invalid_argument("reduceQuery: factor must be >= 1");
  const cv::Size small(channelMap.cols / factor, channelMap.rows / factor);
  if (small.width < 1 || small.height < 1)
    throw std::invalid_argument("reduceQuery: channel map smaller than the factor");
  reducedMap.create(small);
  for (int y = 0; y < small.height; ++y)
    for (int x = 0; x < small.width; ++x) {
      uchar c = kNoChannel;
      for (int dy = 0; dy < factor && c == kNoChannel; ++dy) {
        const uchar* row = channelMap.ptr<uchar>(y * factor + dy) + x * factor;
        for (int dx = 0; dx < factor && c == kNoChannel; ++dx) c = row[dx];
      }
      reducedMap(y, x) = c;
    }
  const float s = 1.0f / static_cast<float>(factor);
  reducedLines.q = lines.q;
  reducedLines.oriented = lines.oriented;
  reducedLines.size = small;
  reducedLines.origin = lines.origin * s;
  reducedLines.lines.clear();
  for (LineSegment l : lines.lines) {
    l.a *= s;
    l.b *= s;
    reducedLines.lines.push_back(l);
  }
}

}  // namespace mfcd::vision
