#pragma once
// Synthetic inputs for the vision tests: random directional edge maps, polygons, templates.
#include <array>
#include <random>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "vision/common/segment.hpp"

namespace mfcd::vision::testing {

// Random segments rasterised into a channel map (each pixel labelled with its segment's
// channel), plus `noise` isolated pixels with random channels. `oriented`: the q channels span
// 2 pi (OrientationChannels).
cv::Mat1b randomChannelMap(std::mt19937& rng, cv::Size size, int q, int segments, int noise, bool oriented = false);

// Random line set: `count` channel-aligned segments of length [minLen, maxLen] inside a box of
// half-size `extent` around the origin (0, 0). `oriented`: an oriented set (a -> b along the
// channel's direction over 2 pi).
LineSet randomLineSet(std::mt19937& rng, int q, int count, double minLen, double maxLen, double extent,
                      bool oriented = false);

// Rasterises a line set into a channel map, origin placed at `at`, using the line fitter's
// convention (pixels of each segment labelled with its channel).
void drawLineSet(cv::Mat1b& channelMap, const LineSet& set, cv::Point2d at);

// Euclidean distance from p to the segment [a, b].
double pointToSegment(cv::Point2d p, cv::Point2d a, cv::Point2d b);

// Every labelled pixel of a channel map as {x, y, channel}.
std::vector<std::array<int, 3>> labelledPixels(const cv::Mat1b& channelMap);

// A random convex polygon (count vertices) inside a circle of `radius` around `centre`.
std::vector<cv::Point2d> randomPolygon(std::mt19937& rng, cv::Point2d centre, double radius, int count);

}  // namespace mfcd::vision::testing
