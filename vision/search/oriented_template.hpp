#pragma once
// A template placed in the hypothesis domain (paper Sec. 3.6): its line set transformed by one
// in-plane rotation, scale and aspect, digitised into segments of the q channels. The search then
// only varies the translation (tx, ty) of the template origin.
#include <vector>

#include <opencv2/core/types.hpp>

#include "vision/common/digital_line.hpp"
#include "vision/common/segment.hpp"

namespace mfcd::vision {

struct Warp {
  double angle = 0;  // in-plane rotation, radians (image axes: positive turns x towards y)
  double scale = 1;
  double aspect = 1;  // x stretched by aspect before rotation
  cv::Matx22d matrix() const;
};

struct OrientedTemplate {
  int templateIndex = 0;
  Warp warp;
  std::vector<DigitalSegment> segments;  // relative to the origin, most pixels first
  int pixels = 0;                        // |U|: total pixel count, the DCM normaliser
  // Conservative bounding box of every pixel for any translation (the digital pattern may move a
  // pixel by one along the minor axis): [x0, x1] x [y0, y1] relative to the origin, inclusive.
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  // Transformed source lines (relative to the origin), kept for the 1-D search.
  std::vector<LineSegment> lines;

  // Translations keeping every pixel inside a width x height image.
  int txMin() const { return -x0; }
  int tyMin() const { return -y0; }
  int txMax(int width) const { return width - 1 - x1; }
  int tyMax(int height) const { return height - 1 - y1; }
};

// Digitises `set` (coordinates relative to set.origin) under `warp`. Segments longer than
// kMaxSegmentSpan+1 pixels are split. Segments shorter than one pixel after warping are dropped.
OrientedTemplate orientTemplate(const LineSet& set, int templateIndex, const Warp& warp);
// The same into `out`, whose vectors and `scratch` keep their storage between calls: no
// allocation once they have grown (the pick cycle's local fits digitise thousands of warps).
void orientTemplate(const LineSet& set, int templateIndex, const Warp& warp, OrientedTemplate& out,
                    std::vector<DigitalSegment>& scratch);
// Grows `out` and `scratch` to hold `set` digitised under any warp that lengthens no line by more
// than `max_stretch` (the warp matrix's largest singular value): orientTemplate into them then
// allocates nothing for such warps, not even the first time.
void reserveOrientedTemplate(const LineSet& set, double max_stretch, OrientedTemplate& out,
                             std::vector<DigitalSegment>& scratch);

// The hypothesis grid of the search: rotations, scales, aspects.
struct WarpGrid {
  double angleMin = 0;  // radians; full turn by default
  double angleMax = 2 * 3.14159265358979323846;
  int angleStepChannels = 1;  // rotation step in channel steps (OrientationChannels::step); 1 keeps channels exact
  std::vector<double> scales{1.0};
  std::vector<double> aspects{1.0};

  // Geometric series helpers for the paper's Sec. 5.2 setup (ratio 1.2 scales, 1.1 aspects).
  static std::vector<double> series(double centre, double ratio, int count);
  std::vector<Warp> warps(int q, bool oriented = false) const;
};

}  // namespace mfcd::vision
