#pragma once
// Correspondences by the directional chamfer criterion (paper Sec. 4.5, Eq. 21): for a model
// edge point u with image direction phi(u), the detected edge pixel
//   v* = argmin_v |u - v| + lambda * |phi(u) - phi(v)|
// where the orientation difference is undirected (modulo pi) and lambda is in px per radian;
// or, in an oriented index (depth edges with their shadow side), modulo 2 pi, so that an edge
// whose near side is the other one is never paired. Orientations are used unquantised, so the
// index returns the exact argmin of Eq. 21.
//
// The index buckets the edge pixels of one DepthEdges map into square cells; a query scans
// rings of cells around u, skips a cell whose nearest pixel is farther than the best cost found
// (or the gate), and stops as soon as a whole ring is. Built once per view image and shared by
// every candidate refined against it; the buffers are reused between builds.

#include "vision/common/orientation.hpp"
#include "vision/edges/depth_edges.hpp"

#include <opencv2/core.hpp>

#include <cstdint>
#include <numbers>
#include <vector>

namespace mfcd::vision {

// The paper's orientation weight: 6 degrees of orientation error cost as much as 1 px
// (orientation.hpp: lambda = 0.5 px per 3-degree channel step at q = 60).
inline constexpr double kDefaultLambdaPxPerRad = 30.0 / std::numbers::pi;

struct EdgeMatch {
  bool found = false;
  float x = 0, y = 0;  // the matched edge pixel (integer coordinates)
  float angle = 0;     // its tangent angle, [0, pi) ([0, 2 pi) from an oriented index)
  double cost = 0;     // Eq. 21 cost in px
};

class DirectionalEdgeIndex {
 public:
  explicit DirectionalEdgeIndex(int cell_px = 8);

  // Indexes the edge pixels of `edges` (edges: 8-bit, non-zero = edge; direction: float
  // tangent angle, same size). Throws std::invalid_argument naming `source` on an empty map or
  // mismatched sizes/types. An edge map without any edge pixel is accepted (every query then
  // finds nothing); callers decide whether that is an error.
  // `oriented`: the directions are oriented tangents ([0, 2 pi), oriented_tangent) and the
  // queries' too; Eq. 21's orientation term then compares them modulo 2 pi, so an edge whose
  // occluder lies on the other side costs lambda * pi more than one on the same side.
  void build(const DepthEdges& edges, const char* source = "edge map", bool oriented = false);
  bool oriented() const { return oriented_; }

  // The Eq. 21 argmin among edge pixels whose cost is <= max_cost_px (the gate); found = false
  // when there is none.
  EdgeMatch nearest(cv::Point2d u, double angle, double lambda_px_per_rad, double max_cost_px) const;

  cv::Size size() const { return size_; }
  int edge_count() const { return static_cast<int>(points_.size()); }

 private:
  struct Entry {
    float x, y, angle;  // angle in [0, pi), or [0, 2 pi) when oriented
  };
  int cell_;
  bool oriented_ = false;
  cv::Size size_;
  int grid_w_ = 0, grid_h_ = 0;
  std::vector<uint32_t> cell_start_;  // grid_w * grid_h + 1 offsets into points_
  // Per cell, which of kAngleBins equal bins of the period its pixels' angles fall in: a query
  // skips a cell whose pixels are all turned too far from its angle (a lower bound on their
  // cost), not only one that lies too far away. Clutter near a part's outline is mostly edges of
  // other orientations; this is where most scanned pixels were rejected.
  static constexpr int kAngleBins = 32;
  std::vector<uint32_t> cell_angles_;
  std::vector<Entry> points_;
  std::vector<uint32_t> fill_;  // build scratch
};

// The obviously-right twin of DirectionalEdgeIndex::nearest for tests: every edge pixel tried.
EdgeMatch nearest_edge_brute_force(const DepthEdges& edges, cv::Point2d u, double angle, double lambda_px_per_rad,
                                   double max_cost_px, bool oriented = false);

}  // namespace mfcd::vision
