#include "vision/pipeline/turn_checks.hpp"

#include "vision/common/rotation.hpp"
#include "vision/model/mesh_turns.hpp"
#include "vision/model/surface_grid.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

namespace mfcd::vision::detail {

std::vector<PoseTurn> mesh_turns(const TemplateDatabase& db) {
  const SurfaceGrid surface = part_surface(db);
  std::vector<PoseTurn> out;
  for (const MeshTurn& m : db.turns.alternatives) {
    PoseTurn& t = out.emplace_back();
    t.S = m.R;
    t.pivot_mm = m.pivot_mm;
    if (m.kind == MeshTurn::Kind::near_symmetry) {
      t.differs = asymmetric_points(db, surface, m.R.t(), nullptr, &m.pivot_mm);
      if (cv::norm(m.R - m.R.t(), cv::NORM_INF) > 1e-9)
        t.differs_turned = asymmetric_points(db, surface, m.R, nullptr, &m.pivot_mm);
      t.screen = true;
    }
  }
  return out;
}

// Plate turns: a plate with a 2-fold symmetry about its normal (the diamond, the ellipse, the T-nut:
// plate_axis, found from the mesh) seen on edge or steeply tilted shows an outline that changes
// little when it turns about that normal,
// and fits from the search's hypotheses stop 10-25 degrees off, on the flank of the truth's basin:
// in the capped set's scene 7 image 1 an ellipse on edge fitted 24.5 degrees off scores 0.554, the
// fit from the truth 0.560. Fits started +-15 degrees about z reach the truth's basin. The points
// where the two poses differ are mostly those of two template views a few degrees apart, which
// say nothing (judged by compare: 5 correct plates turned wrong, none fixed, on five sets), so
// the turned fit is taken when its rank is higher, and only for hypotheses the cell would pick
// (rank at least config/cell.yaml's min_score 0.1): below that, a higher rank is noise (4 fixed and
// 4 broken without it, all the broken ranked below 0.09).

const MeshTurn* plate_symmetry(const TemplateDatabase& db) {
  const cv::Vec3d thin(db.turns.principal_axes(2, 0), db.turns.principal_axes(2, 1), db.turns.principal_axes(2, 2));
  for (const MeshTurn& s : db.turns.symmetries)
    if (s.order == 2 && std::abs(s.axis.dot(thin)) >= std::cos(kPlateAxisMaxDeg * CV_PI / 180)) return &s;
  return nullptr;
}

std::optional<cv::Vec3d> plate_axis(const TemplateDatabase& db) {
  const MeshTurn* sym = plate_symmetry(db);
  return sym ? std::optional<cv::Vec3d>(sym->axis) : std::nullopt;
}

std::vector<PoseTurn> plate_turns(const TemplateDatabase& db) {
  std::vector<PoseTurn> out;
  const MeshTurn* sym = plate_symmetry(db);
  if (!sym) return out;
  for (const double sign : {1.0, -1.0}) {
    PoseTurn& t = out.emplace_back();
    t.S = axis_rotation(sym->axis, sign * kPlateTurnDeg * CV_PI / 180);
    t.pivot_mm = sym->pivot_mm;
    t.by_rank = true;
  }
  return out;
}

bool turn_is_better(const TemplatePoseFit::Difference& d) {
  if (d.only_b >= kFlipMinPoints)
    return d.found_b >= d.found_a + kFlipMargin ||
           (d.only_a >= kFlipMinPoints && d.cost_b + kFlipCostMarginPx <= d.cost_a);
  return d.only_b <= kFlipHiddenMaxPoints && d.only_a >= kFlipMinPoints && d.cost_a >= kFlipAbsentCostPx;
}

}  // namespace mfcd::vision::detail
