#include "vision/pose/edge_correspondence.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <stdexcept>
#include <string>

namespace mfcd::vision {

namespace {
// An angle in [0, period): nearest() relies on its entries' range.
float modulo(float angle, double period) {
  const auto top = static_cast<float>(period);
  if (angle >= 0 && angle < top) return angle;
  const double r = std::fmod(static_cast<double>(angle), period);
  const float wrapped = static_cast<float>(r < 0 ? r + period : r);
  return wrapped < top ? wrapped : 0.f;  // the period rounds up in float
}

// The bin of the angle bins (`bins` equal parts of [0, period)) that angle a, in [0, period), falls
// in: one formula for the cells' masks and the queries.
int angle_bin(double a, double period, int bins) { return std::min(bins - 1, static_cast<int>(a * (bins / period))); }
}  // namespace

DirectionalEdgeIndex::DirectionalEdgeIndex(int cell_px) : cell_(cell_px) {
  if (cell_px < 1) throw std::invalid_argument("DirectionalEdgeIndex: cell size must be >= 1 px");
}

void DirectionalEdgeIndex::build(const DepthEdges& edges, const char* source, bool oriented) {
  // The source's name goes into a string only on the way out (build() runs every cycle).
  auto name = [source] { return std::string(source); };
  if (edges.edges.empty()) throw std::invalid_argument(name() + ": the edge image is empty");
  if (edges.edges.type() != CV_8UC1) throw std::invalid_argument(name() + ": edges must be 8-bit single channel");
  if (edges.direction.size() != edges.edges.size() || edges.direction.type() != CV_32FC1)
    throw std::invalid_argument(name() + ": direction must be a float image of the edges' size (" +
                                std::to_string(edges.edges.cols) + "x" + std::to_string(edges.edges.rows) + "), got " +
                                std::to_string(edges.direction.cols) + "x" + std::to_string(edges.direction.rows));
  oriented_ = oriented;
  const double period = oriented ? 2 * std::numbers::pi : std::numbers::pi;
  size_ = edges.edges.size();
  grid_w_ = (size_.width + cell_ - 1) / cell_;
  grid_h_ = (size_.height + cell_ - 1) / cell_;
  const size_t cells = static_cast<size_t>(grid_w_) * grid_h_;
  cell_start_.assign(cells + 1, 0);
  // Counting sort by cell: count, prefix sums, place.
  for (int y = 0; y < size_.height; ++y) {
    const uint8_t* e = edges.edges.ptr<uint8_t>(y);
    const uint32_t row = static_cast<uint32_t>(y / cell_) * grid_w_;
    for (int x = 0; x < size_.width; ++x)
      if (e[x]) ++cell_start_[row + static_cast<uint32_t>(x / cell_) + 1];
  }
  for (size_t c = 0; c < cells; ++c) cell_start_[c + 1] += cell_start_[c];
  points_.resize(cell_start_[cells]);
  fill_.assign(cell_start_.begin(), cell_start_.end() - 1);
  cell_angles_.assign(cells, 0);
  for (int y = 0; y < size_.height; ++y) {
    const uint8_t* e = edges.edges.ptr<uint8_t>(y);
    const float* d = edges.direction.ptr<float>(y);
    const uint32_t row = static_cast<uint32_t>(y / cell_) * grid_w_;
    for (int x = 0; x < size_.width; ++x)
      if (e[x]) {
        const uint32_t c = row + static_cast<uint32_t>(x / cell_);
        const float a = modulo(d[x], period);
        points_[fill_[c]++] = {static_cast<float>(x), static_cast<float>(y), a};
        cell_angles_[c] |= 1u << angle_bin(a, period, kAngleBins);
      }
  }
}

EdgeMatch DirectionalEdgeIndex::nearest(cv::Point2d u, double angle, double lambda, double max_cost) const {
  EdgeMatch best;
  if (points_.empty() || !(max_cost >= 0) || !std::isfinite(u.x) || !std::isfinite(u.y) || !std::isfinite(angle))
    return best;
  // The query's angle is taken modulo the period once: the entries' lie in [0, period) (build),
  // so the difference of the two is min(d, period - d) of d = |a - b|, without a remainder per
  // pixel.
  const double period = oriented_ ? 2 * std::numbers::pi : std::numbers::pi;
  double a = std::fmod(angle, period);
  if (a < 0) a += period;
  // Clamp u into the pixel area: the clamped point is no farther from any edge pixel than u
  // (projection onto a convex set), so the bounds computed from it stay valid lower bounds.
  const double cxu = std::clamp(u.x, -0.5, size_.width - 0.5);
  const double cyu = std::clamp(u.y, -0.5, size_.height - 0.5);
  const int gx = std::clamp(static_cast<int>(std::floor((cxu + 0.5) / cell_)), 0, grid_w_ - 1);
  const int gy = std::clamp(static_cast<int>(std::floor((cyu + 0.5) / cell_)), 0, grid_h_ - 1);
  double best_cost = max_cost;
  const int max_ring = std::max(grid_w_, grid_h_);
  // The distance from the clamped u to the nearest pixel of cell c along one axis.
  auto gap = [this](double v, int c) { return std::max({0.0, c * cell_ - v, v - ((c + 1) * cell_ - 1)}); };
  // The least orientation difference between the query's angle and any angle of bin b: 0 when
  // the bin holds it, else the circular distance to the nearer end of the bin.
  const double bin_width = period / kAngleBins;
  const int own_bin = angle_bin(a, period, kAngleBins);
  auto turn_bound = [&](uint32_t bins) {
    if (bins & (1u << own_bin)) return 0.0;
    double least = period;
    while (bins) {
      const int b = std::countr_zero(bins);
      bins &= bins - 1;
      for (double end : {b * bin_width, (b + 1) * bin_width}) {
        const double d = std::abs(a - end);
        least = std::min(least, std::min(d, period - d));
      }
    }
    return least;
  };
  auto scan_cell = [&](int cx, int cy) {
    // A cell all of whose pixels are farther than the best cost so far cannot hold the argmin.
    const double bx = gap(cxu, cx), by = gap(cyu, cy);
    if (bx * bx + by * by > best_cost * best_cost) return;
    const size_t c = static_cast<size_t>(cy) * grid_w_ + cx;
    // Nor can one whose pixels are all turned too far: a lower bound of their cost, less a
    // margin for the float angles' binning, so that no pixel that could win is skipped.
    if (std::sqrt(bx * bx + by * by) + lambda * turn_bound(cell_angles_[c]) - 1e-6 > best_cost) return;
    for (uint32_t i = cell_start_[c]; i < cell_start_[c + 1]; ++i) {
      const Entry& p = points_[i];
      const double dx = p.x - u.x, dy = p.y - u.y;
      const double d2 = dx * dx + dy * dy;
      if (d2 > best_cost * best_cost) continue;
      const double d = std::abs(a - p.angle);
      const double cost = std::sqrt(d2) + lambda * std::min(d, period - d);
      if (cost < best_cost || (cost == best_cost && !best.found)) {
        best_cost = cost;
        best = {true, p.x, p.y, p.angle, cost};
      }
    }
  };
  for (int r = 0; r <= max_ring; ++r) {
    const int x0 = gx - r, x1 = gx + r, y0 = gy - r, y1 = gy + r;
    // Ring r lies outside the cells [x0 + 1, x1 - 1] x [y0 + 1, y1 - 1], which hold u: every
    // pixel of it is at least the distance from u to that block's border away.
    if (r >= 1 && std::min({cxu - (x0 + 1) * cell_ + 1, x1 * cell_ - cxu, cyu - (y0 + 1) * cell_ + 1,
                            y1 * cell_ - cyu}) > best_cost)
      break;
    for (int cy = std::max(y0, 0); cy <= std::min(y1, grid_h_ - 1); ++cy) {
      if (cy == y0 || cy == y1) {
        for (int cx = std::max(x0, 0); cx <= std::min(x1, grid_w_ - 1); ++cx) scan_cell(cx, cy);
      } else {
        if (x0 >= 0) scan_cell(x0, cy);
        if (x1 < grid_w_ && x1 != x0) scan_cell(x1, cy);
      }
    }
  }
  return best;
}

EdgeMatch nearest_edge_brute_force(const DepthEdges& edges, cv::Point2d u, double angle, double lambda, double max_cost,
                                   bool oriented) {
  EdgeMatch best;
  for (int y = 0; y < edges.edges.rows; ++y)
    for (int x = 0; x < edges.edges.cols; ++x) {
      if (!edges.edges(y, x)) continue;
      const double turn = oriented ? oriented_angle_difference(angle, edges.direction(y, x))
                                   : undirected_angle_difference(angle, edges.direction(y, x));
      const double cost = std::hypot(x - u.x, y - u.y) + lambda * turn;
      if (cost <= max_cost && (!best.found || cost < best.cost))
        best = {true, static_cast<float>(x), static_cast<float>(y), edges.direction(y, x), cost};
    }
  return best;
}

}  // namespace mfcd::vision
