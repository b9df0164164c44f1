#pragma once
// DT3, the three-dimensional distance transform (paper Sec. 3.4, Eqs. 8-11):
//   DT3(x, c) = min over query edge pixels v of ( |x - v| + lambda * dist(c, channel(v)) ),
// truncated at maxCost. Computed as q per-channel exact Euclidean distance transforms followed,
// per pixel, by the forward and backward circular recursions over orientation.
//
// Storage: one byte per entry in fixed point (1/kCostScale px), channel-major planes of
// width x height. At 640x480 and q = 60 that is 18.4 MB; see docs/benchmarks.md.
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "vision/common/orientation.hpp"

namespace mfcd::vision {

struct Dt3Params {
  int q = 60;
  // Channels span 2 pi (edge polarity, OrientationChannels): the transform itself only sees
  // channel ids and their circular distance, so this only tells IDT3 and the matchers the
  // channels' directions. q must then be even.
  bool oriented = false;
  // Oriented only: what an edge of the other polarity costs beyond its undirected orientation
  // difference, px. With oriented channels alone an edge's reverse is q/2 steps away (lambda *
  // q/2, the truncation at the paper's settings); a finite penalty makes the cost
  //   min(lambda * d(c, c'), lambda * d(c + q/2, c') + polarityPenalty)
  // (0 gives the undirected transform, infinity the oriented one). Quantised to 1/8 px.
  double polarityPenalty = std::numeric_limits<double>::infinity();
  double lambda = 0.5;    // px per channel step (q = 60: 6 degrees ~ 1 px); quantised to 1/8 px
  double maxCost = 30.0;  // truncation, px; at most 255/kCostScale = 31.875

  void validate() const;  // throws std::invalid_argument naming the field
  int lambdaUnits() const;
  int capUnits() const;
  int polarityPenaltyUnits() const;  // capped at capUnits() (no smaller cost can come of it)
};

class DirectionalDistanceTransform {
 public:
  // `channelMap`: per pixel the orientation channel of the query edge there, or kNoChannel
  // (the line fitter's channelMap). Buffers are reused between calls of the same size.
  void compute(const cv::Mat1b& channelMap, const Dt3Params& params);

  int width() const { return width_; }
  int height() const { return height_; }
  int q() const { return q_; }
  OrientationChannels channels() const { return OrientationChannels(q_, params_.oriented); }
  const Dt3Params& params() const { return params_; }
  const uint8_t* plane(int channel) const { return data_.data() + static_cast<size_t>(channel) * width_ * height_; }
  uint8_t at(int channel, int x, int y) const { return plane(channel)[static_cast<size_t>(y) * width_ + x]; }
  size_t bytes() const { return data_.size(); }

 private:
  // One thread's buffers of the per-channel distance, kept between computes.
  struct Scratch {
    std::vector<uint8_t> g;  // vertical distances
    std::vector<int> v;      // lower envelope: parabola sites ...
    std::vector<float> z;    // ... and their boundaries
  };
  void channelDistance(int channel, std::span<const int> pixels, Scratch& scratch);
  void orientationRecursion(int row);

  Dt3Params params_;
  int width_ = 0, height_ = 0, q_ = 0;
  std::vector<uint8_t> data_;
  std::vector<uint8_t> sqrtTable_;  // squared distance -> fixed-point distance, capped
  // Kept between computes so that a compute of the same size allocates nothing once grown.
  std::vector<int> channelPixels_;    // edge pixels (y * width + x), grouped by channel
  std::vector<size_t> channelStart_;  // channel c's are [start[c], start[c + 1])
  std::vector<Scratch> scratch_;      // per thread
};

}  // namespace mfcd::vision
