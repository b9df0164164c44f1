#pragma once
// Line-based representation of an edge map (paper Sec. 3.3): a RANSAC variant that hypothesises
// segments from edge points and their local directions, keeps the one with the largest contiguous
// support, removes its points and repeats until the best remaining support is below a few points.
//
// Hypotheses are lines of the q channel directions through every edge pixel (around its local
// direction); the accepted one is refitted to its support with a free direction so its endpoints
// are where the edge really ends, and labelled with the nearest channel. Matching needs segments
// along channel directions (Sec. 3.5): the digitiser (search/oriented_template.hpp) splits a
// segment whose true direction is between channels into pieces that stay within half a pixel.
#include <opencv2/core/mat.hpp>

#include <cmath>
#include <utility>
#include <vector>

#include "vision/common/segment.hpp"

namespace mfcd::vision {

struct LineFitParams {
  int q = 60;                // orientation channels
  double residual = 1.0;     // gamma: max perpendicular distance of a support point, px
  int maxGap = 2;            // longest run of missing pixels bridged inside one segment, px
  int minSupport = 10;       // a segment must explain at least this many edge pixels
  int directionRadius = 2;   // neighbourhood (2r+1)^2 for local edge directions
  int channelSpread = 1;     // hypotheses per seed: its local channel +- this many channels
  int refineIterations = 2;  // re-centre the line on its support this many times
  // Edge polarity (docs/fdcm.md "Search with edge polarity"): each fitted segment is also
  // oriented so that its left normal points into the shadow side, by the majority of its support
  // pixels' shadow normals. The fit itself is the undirected one (same segments, same pixels);
  // the result then has 2q channels over 2 pi (LineSet::oriented), and its channel map holds
  // them. Needs the shadow map.
  bool oriented = false;

  void validate() const;  // throws std::invalid_argument naming the bad field
};

struct LineFitResult {
  LineSet set;
  // Per pixel: the channel of the segment that claimed it, or kNoChannel. This is the
  // directional edge map DT3 is built from (noise pixels no segment explains are dropped).
  cv::Mat1b channelMap;
  int inputEdgePixels = 0;
  int explainedEdgePixels = 0;
};

// `edges`: nonzero = edge pixel. `direction` (optional, same size, radians): the edge tangent per
// pixel, e.g. from the depth-edge extractor; without it local directions come from the
// neighbourhood's principal axis. `shadow` (params.oriented only, same size): per pixel the
// angle of the normal into the shadow side (DepthEdges::shadow). Throws std::invalid_argument on
// an empty image, a map of another size, or an oriented fit without a shadow map.
LineFitResult fitLines(const cv::Mat1b& edges, const LineFitParams& params = {}, const cv::Mat1f* direction = nullptr,
                       const cv::Mat1f* shadow = nullptr);

// How a trace walks a direction: along its major image axis, the minor coordinate moving by
// `slope` per step, collecting a band of +-`band` around it. Depends on the direction only, so
// the fit computes it once per channel: most traces are a few pixels long, and the
// trigonometry of each cost more than its walk.
struct TraceDirection {
  bool xm = true;    // x is the major axis
  double slope = 0;  // minor = minor0 + slope * (major - major0)
  double band = 0;   // the perpendicular residual as a minor-axis half width: r * sqrt(1 + slope^2)

  TraceDirection() = default;
  TraceDirection(double phi, double residual)
      : xm(std::abs(std::cos(phi)) >= std::abs(std::sin(phi))),
        slope(xm ? std::tan(phi) : std::cos(phi) / std::sin(phi)),
        band(residual * std::sqrt(1.0 + slope * slope)) {}
};

// One hypothesis of the line fit: a line of channel `channel` through edge pixel `seed`.
struct LineHypothesis {
  int score;    // its support (edge pixels in its band), >= 0
  int seed;     // index into the edge pixel list
  int channel;  // hypothesised direction
  // Priority order: higher score first, then lower seed, then lower channel (a max-heap's order).
  bool operator<(const LineHypothesis& o) const {
    return score != o.score ? score < o.score : seed != o.seed ? seed > o.seed : channel > o.channel;
  }
};

// The line fit's pending hypotheses, popped highest score first and,
// among equal scores, lowest seed then lowest channel: the order of one binary heap over all of
// them, which it replaces. There are 2 * channelSpread + 1 per edge pixel and the lazy greedy
// pops each at least once: the binary heap's sifts over ~10^4-10^5 entries were a sixth of the
// greedy loop. Here each score has a list of its entries, ordered only when it becomes the top
// score (one sort); pops then take the next of that order in O(1), and the greedy's pushes (a
// re-scored hypothesis, always below the top score) prepend to a list in O(1).
// Entries live in one pool, a pushed entry in the slot its pop freed: once the pool, the per
// score heads (reserve) and the sort buffer have grown, nothing allocates (the pick cycle).
class HypothesisQueue {
 public:
  // Empties the queue; scores up to max_score then need no allocation.
  void reset(int max_score);
  // The initial fill, in any order (score >= 0); build() then orders it.
  void add(const LineHypothesis& h);
  void build();
  // After build(): an entry scored below the top score (a popped one, re-scored lower); throws
  // std::invalid_argument otherwise (the greedy never does that, and the order of the top score
  // is fixed when it is reached).
  void push(const LineHypothesis& h);
  LineHypothesis pop();  // the first entry; throws std::logic_error when empty
  bool empty() const { return top_ < 0; }
  int top_score() const { return top_; }  // the first entry's score; -1 when empty

 private:
  struct Key {
    int seed, channel;
    // Sorted so that the first entry (lowest seed, then channel) is the last.
    bool operator<(const Key& o) const { return seed != o.seed ? seed > o.seed : channel > o.channel; }
  };
  struct Node {
    Key key;
    int next;  // the next node of its score's list, -1 at the end
  };
  void link(int score, const Key& key);
  void collect_top();  // moves the top score's list into `order_`, sorted
  std::vector<Node> pool_;
  std::vector<int> free_;   // pool slots of entries popped (their list nodes were collected)
  std::vector<int> heads_;  // per score, the first node of its list, -1 when empty
  std::vector<Key> order_;  // the top score's entries, sorted; popped from the back
  int top_ = -1;            // highest score with an entry, -1 when empty
};

// fitLines with its buffers kept between calls, for the pick cycle: once they (and `out`'s)
// have grown to an image's needs, fitting an image of that size and no more edges allocates
// nothing (with a direction map; without one the local directions are computed into a new
// vector). Same result as fitLines.
class LineFitter {
 public:
  explicit LineFitter(const LineFitParams& params = {});  // throws std::invalid_argument (validate)
  void fit(const cv::Mat1b& edges, const cv::Mat1f* direction, LineFitResult& out, const cv::Mat1f* shadow = nullptr);
  const LineFitParams& params() const { return params_; }

  using Hypothesis = LineHypothesis;

 private:
  LineFitParams params_;
  std::vector<cv::Point> pts_;
  cv::Mat1b alive_;
  std::vector<float> dir_;
  std::vector<int> seed_scores_;       // per edge pixel, its 2 * channelSpread + 1 hypotheses' support
  std::vector<TraceDirection> walks_;  // per channel, how a trace walks it (from the params)
  HypothesisQueue queue_;
  std::vector<cv::Point> support_, next_;
  std::vector<std::pair<float, int>> order_;  // sortLongestFirst's buffers
  std::vector<LineSegment> sorted_;
};

// The query at 1/factor of its resolution, for a coarse search (PipelineConfig::search_downsample):
// every line scaled by 1/factor (channels unchanged), and the channel map reduced so that a pixel
// keeps a channel when any pixel of its factor x factor block has one (the first in row order).
// Rasterising the scaled lines instead gives thinner lines, which the chamfer search matches
// worse (measured on mfc-sim bins: 100 failures against 90 over three dev sets). Output buffers
// are reused (no allocation once grown). Throws std::invalid_argument for factor < 1 or a
// channel map smaller than factor.
void reduceQuery(const LineSet& lines, const cv::Mat1b& channelMap, int factor, LineSet& reducedLines,
                 cv::Mat1b& reducedMap);

}  // namespace mfcd::vision
