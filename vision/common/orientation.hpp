#pragma once
// Orientation channels (paper Sec. 3.4): edge directions are undirected, modulo pi, and are
// quantised into q evenly spaced channels; channel c is centred on the angle c*pi/q.
// Oriented channels (an extension: the search with edge polarity, docs/fdcm.md) span 2 pi
// instead: channel c is centred on c*2pi/q, and c and c + q/2 are the two polarities of one
// undirected direction.
//
// Angle convention everywhere in vision/: image coordinates (x right, y down), an angle is
// atan2(dy, dx) in those coordinates, reduced to [0, pi).
//
// Units of lambda (the orientation weight of DCM, Eq. 6): pixels per channel step. With the
// paper's q = 60 a step is 3 degrees, so lambda = 0.5 px/step means 6 degrees cost as much as one
// pixel, which is the paper's choice ("6 deg error ... same penalty as a 1-pixel distance").
// In radians that is lambda_rad = lambda * q / pi = 9.55 px/rad.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace mfcd::vision {

// Undirected angle difference in [0, pi/2] of two angles given modulo pi.
inline double undirected_angle_difference(double a, double b) {
  const double d = std::fmod(std::abs(a - b), std::numbers::pi);
  return std::min(d, std::numbers::pi - d);
}
// Difference in [0, pi] of two oriented angles (given modulo 2 pi: an edge tangent that also says
// which side is the occluder, oriented_tangent in vision/edges).
inline double oriented_angle_difference(double a, double b) {
  const double d = std::fmod(std::abs(a - b), 2 * std::numbers::pi);
  return std::min(d, 2 * std::numbers::pi - d);
}

// Whether the shadow side `shadow` (an angle in [0, 2 pi) as in DepthEdges::shadow: the edge
// normal pointing into the shadow) lies on the left of the direction `tangent` (in [-pi, 2 pi)),
// i.e. sin(shadow - tangent) >= 0: their difference, brought into [0, 2 pi), is at most pi.
// Without trigonometry: the line fitter asks it of every claimed pixel of every cycle.
inline bool shadow_left_of(double tangent, double shadow) {
  constexpr double kTurn = 2 * std::numbers::pi;
  double turn = shadow - tangent;
  if (turn < 0) turn += kTurn;
  if (turn >= kTurn) turn -= kTurn;
  return turn <= kTurn / 2;
}

// Costs are stored in fixed point: one unit is 1/kCostScale pixel. 8 gives 1/8 px resolution
// and lets a truncated per-pixel cost (<= 31.875 px) live in one byte.
inline constexpr int kCostScale = 8;
inline constexpr int kMaxChannels = 180;  // channel ids must fit a byte next to the "no edge" id
inline constexpr unsigned char kNoChannel = 255;

class OrientationChannels {
 public:
  // `oriented`: the q channels span a full turn [0, 2 pi) instead of [0, pi): an oriented edge
  // also says which of its sides is the occluder (edge polarity, oriented_tangent in
  // vision/edges), and channel c + q/2 is channel c's direction reversed. q must then be even.
  explicit OrientationChannels(int q, bool oriented = false) : q_(q), oriented_(oriented) {
    if (q <= 0 || q > kMaxChannels)
      throw std::invalid_argument("orientation channels: q must be in 1.." + std::to_string(kMaxChannels) + ", got " +
                                  std::to_string(q));
    if (oriented && q % 2 != 0)
      throw std::invalid_argument("orientation channels: oriented channels need an even q, got " + std::to_string(q));
  }
  int q() const { return q_; }
  bool oriented() const { return oriented_; }
  double period() const { return oriented_ ? 2 * std::numbers::pi : std::numbers::pi; }
  double step() const { return period() / q_; }
  double angleOf(int channel) const { return channel * step(); }

  // Channel whose centre is nearest to the angle (taken modulo the period).
  int channelOf(double angle) const {
    double a = std::fmod(angle, period());
    if (a < 0) a += period();
    int c = static_cast<int>(std::lround(a / step()));
    return c % q_;
  }
  // Circular distance between two channels, in channel steps (0 .. q/2).
  int distance(int a, int b) const {
    int d = std::abs(a - b) % q_;
    return d <= q_ - d ? d : q_ - d;
  }
  int wrap(int c) const {
    c %= q_;
    return c < 0 ? c + q_ : c;
  }
  // A channel is "x-major" when its direction is closer to the x axis than to the y axis
  // (the 45-degree channels count as x-major). Decided on integers so it never flickers; a
  // channel and its reverse (oriented) have the same axis.
  bool xMajor(int channel) const {
    const int half = oriented_ ? q_ / 2 : q_;  // channels per half turn
    const int c = channel % half;
    return 4 * c <= half || 4 * c >= 3 * half;
  }
  // Minor-axis change per major-axis step of the channel's direction (|slope| <= 1 by the choice
  // of major axis): tan(phi) for x-major channels, cot(phi) for y-major ones. The same for a
  // channel and its reverse.
  double minorSlope(int channel) const {
    // From the undirected angle, so that a channel and its reverse share one digital pattern
    // bit for bit (tan(phi + pi) need not round like tan(phi)).
    const double phi = angleOf(oriented_ ? channel % (q_ / 2) : channel);
    return xMajor(channel) ? std::tan(phi) : std::cos(phi) / std::sin(phi);
  }

 private:
  int q_;
  bool oriented_;
};

}  // namespace mfcd::vision
