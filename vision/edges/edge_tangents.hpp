#pragma once
// Tangent directions of edge pixels from their pixel chains: the principal axis of the edge
// pixels in a small window around each. The per-pixel gradient directions of the depth-edge
// extractor scatter by 10-20 degrees along a straight depth edge; the chain direction does not.
// Templates (their model points) and the pose fits use this one estimator on both sides, so
// Eq. 21's orientation term compares like with like.

#include <opencv2/core.hpp>

namespace mfcd::vision {

// Tangent angle ([0, pi), image axes) of every edge pixel of `edges` (non-zero = edge): the
// principal axis of the edge pixels within a (2 radius + 1)^2 window, i.e. the local direction
// of the pixel chain. 0 off edges. With `shadow` (DepthEdges::shadow, the edges' size) each is
// oriented by it (oriented_tangent): [0, 2 pi), the left normal pointing into the shadow.
void edge_tangents(const cv::Mat1b& edges, cv::Mat1f& direction, int radius = 3, const cv::Mat1f* shadow = nullptr);
float edge_tangent_at(const cv::Mat1b& edges, int x, int y, int radius = 3);

}  // namespace mfcd::vision
