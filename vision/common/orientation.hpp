#pragma once
// Orientation channels (paper Sec. 3.4): edge directions are undirected, modulo pi, and are
// quantised into q evenly spaced channels; channel c is centred on the angle c*pi/q.
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

// Costs are stored in fixed point: one unit is 1/kCostScale pixel. 8 gives 1/8 px resolution
// and lets a truncated per-pixel cost (<= 31.875 px) live in one byte.
inline constexpr int kCostScale = 8;
inline constexpr int kMaxChannels = 180;  // channel ids must fit a byte next to the "no edge" id
inline constexpr unsigned char kNoChannel = 255;

class OrientationChannels {
public:
  explicit OrientationChannels(int q) : q_(q) {
    if (q <= 0 || q > kMaxChannels)
      throw std::invalid_argument("orientation channels: q must be in 1.." + std::to_string(kMaxChannels) +
                                  ", got " + std::to_string(q));
  }
  int q() const { return q_; }
  double step() const { return std::numbers::pi / q_; }
  double angleOf(int channel) const { return channel * step(); }

  // Channel whose centre is nearest to the (undirected) angle.
  int channelOf(double angle) const {
    double a = std::fmod(angle, std::numbers::pi);
    if (a < 0) a += std::numbers::pi;
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
  // (the 45-degree channels count as x-major). Decided on integers so it never flickers.
  bool xMajor(int channel) const { return 4 * channel <= q_ || 4 * channel >= 3 * q_; }
  // Minor-axis change per major-axis step of the channel's direction (|slope| <= 1 by the choice
  // of major axis): tan(phi) for x-major channels, cot(phi) for y-major ones.
  double minorSlope(int channel) const {
    const double phi = angleOf(channel);
    return xMajor(channel) ? std::tan(phi) : std::cos(phi) / std::sin(phi);
  }

private:
  int q_;
};

}  // namespace mfcd::vision
