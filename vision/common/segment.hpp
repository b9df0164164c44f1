#pragma once
// Line segments: the line-based representation of an edge map (paper Sec. 3.3).
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core/types.hpp>

#include "vision/common/orientation.hpp"

namespace mfcd::vision {

// A fitted segment. Its direction is exactly the centre of `channel` (the fitter enforces this),
// a and b lie on the fitted line, and `support` counts the edge pixels it explains. In an
// oriented set (LineSet::oriented) the direction from a to b is the edge's oriented direction:
// its left normal (-sin, cos) points into the shadow side, away from the occluder.
struct LineSegment {
  cv::Point2f a, b;
  int channel = 0;
  int support = 0;
  float length() const { return static_cast<float>(cv::norm(b - a)); }
};

// A set of segments with the geometry it was made for. `origin` is the template's reference point
// (detections report where the origin lands), `size` the edge map the lines came from.
struct LineSet {
  int q = 60;
  bool oriented = false;  // channels span 2 pi (OrientationChannels); a -> b says the polarity
  cv::Size size;
  cv::Point2f origin;
  std::vector<LineSegment> lines;  // longest first

  size_t totalPixels() const;  // sum over segments of their pixel counts (the template's |U|)
};

void sortLongestFirst(std::vector<LineSegment>& lines);
// The set without polarity: q/2 channels over pi, each line's channel modulo q/2 (its endpoints
// unchanged). An undirected set is returned as it is.
LineSet withoutPolarity(const LineSet& set);
// The same order (longest first, equal lengths in their order) through kept buffers: no
// allocation once they have grown (std::stable_sort allocates a temporary buffer each call).
void sortLongestFirst(std::vector<LineSegment>& lines, std::vector<std::pair<float, int>>& order,
                      std::vector<LineSegment>& scratch);

// Text line files (format in docs/line-file.md):
//   mfcd-lines 1
//   q 60
//   oriented 1                 optional: channels span 2 pi, a -> b is the oriented direction
//   size <width> <height>
//   origin <x> <y>
//   <x1> <y1> <x2> <y2>        one segment per line, any count; '#' starts a comment
// The channel of each segment is recomputed from its endpoints. Malformed input throws
// std::runtime_error naming the file, the line number and what was wrong.
LineSet readLineFile(const std::filesystem::path& path);
LineSet parseLineText(const std::string& text, const std::string& sourceName);
void writeLineFile(const std::filesystem::path& path, const LineSet& set);

}  // namespace mfcd::vision
