#include "vision/pipeline/part_model.hpp"

#include "vision/common/parallel_for.hpp"
#include "vision/common/segment.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

namespace mfcd::vision::detail {

PartModel load_part_model(const std::filesystem::path& file, const CameraConfig& camera, const PipelineConfig& config) {
  PartModel part;
  part.file = file.string();
  part.db = load_template_database(file);
  check_template_camera(part.db, camera, part.file);
  // The search's channels: the templates' own (oriented) ones when the search uses polarity,
  // else the same lines without it.
  if (part.db.oriented && !(config.search_polarity && config.cost == PipelineConfig::Cost::fdcm)) {
    for (TemplateView& view : part.db.views) view.lines = withoutPolarity(view.lines);
    part.db.q /= 2;
    part.db.oriented = false;
  }
  WarpGrid grid;
  grid.scales.clear();
  if (config.distances_mm.empty()) grid.scales.push_back(1.0);
  for (double d : config.distances_mm) {
    if (!(d > 0)) throw std::runtime_error("pipeline: distances_mm must be positive");
    grid.scales.push_back(part.db.distance_mm / d);
  }
  part.warps = grid.warps(part.db.q, part.db.oriented);
  part.oriented.resize(part.db.views.size());
  for (size_t v = 0; v < part.db.views.size(); ++v) {
    auto& list = part.oriented[v];
    list.reserve(part.warps.size());
    for (const Warp& w : part.warps) {
      OrientedTemplate t = orientTemplate(part.db.views[v].lines, static_cast<int>(v),
                                          Warp{w.angle, w.scale / config.search_downsample, w.aspect});
      // The line search only needs the longest lines as guides.
      if (t.lines.size() > 8) {
        sortLongestFirst(t.lines);
        t.lines.resize(8);
      }
      list.push_back(std::move(t));
    }
  }
  part.neighbours = view_neighbours(part.db, config.view_stride);
  part.symmetries = SymmetryGroup(part.db.turns);
  part.searched.assign(part.db.views.size(), 0);
  return part;
}

void find_turns(std::vector<PartModel>& parts, int threads) {
  parallel_for(0, static_cast<int>(parts.size()), threads, 1, [&](int i) {
    PartModel& part = parts[static_cast<size_t>(i)];
    part.flips = mesh_turns(part.db);
    for (PartModel::Turn& t : plate_turns(part.db)) part.flips.push_back(std::move(t));
    part.plate_axis = plate_axis(part.db);
  });
}

// Angle between two viewing directions of a part, the smallest over the copies under `sym` (the
// views' fold: views a coarser symmetry would call the same still show different edges).
double view_angle(const PartSymmetry& sym, const cv::Vec3d& a, const cv::Vec3d& b) {
  auto angle = [](const cv::Vec3d& u, const cv::Vec3d& v) { return std::acos(std::clamp(u.dot(v), -1.0, 1.0)); };
  if (sym.kind == PartSymmetry::Kind::continuous_z)
    return std::abs(std::acos(std::clamp(a[2], -1.0, 1.0)) - std::acos(std::clamp(b[2], -1.0, 1.0)));
  double best = CV_PI;
  for (const cv::Matx33d& S : sym.discrete_rotations()) best = std::min(best, angle(a, S * b));
  return best;
}

// The fine stage's neighbours of every view. A true pose lies within about 0.6 spacings of its
// nearest view (K directions on the sphere are sqrt(4 pi / K) apart), so the coarse view that
// found it lies within 0.6 sqrt(stride) spacings, and the view nearest the truth within
// 0.6 (sqrt(stride) + 1) spacings of that coarse view.
std::vector<std::vector<int>> view_neighbours(const TemplateDatabase& db, int stride) {
  const size_t n = db.views.size();
  std::vector<std::vector<int>> out(n);
  if (stride <= 1 || n == 0) return out;
  const double spacing = std::sqrt(4 * CV_PI / std::max(1, db.sphere_samples));
  const double radius = 0.6 * (std::sqrt(double(stride)) + 1.0) * spacing;
  std::vector<std::pair<double, int>> near;
  for (size_t v = 0; v < n; ++v) {
    near.clear();
    for (size_t u = 0; u < n; ++u) {
      if (u == v) continue;
      const double a = view_angle(db.views_symmetry, db.views[v].view_direction, db.views[u].view_direction);
      if (a <= radius) near.emplace_back(a, static_cast<int>(u));
    }
    std::sort(near.begin(), near.end());
    for (const auto& [a, u] : near) out[v].push_back(u);
  }
  return out;
}

}  // namespace mfcd::vision::detail
