#include "vision/pipeline/turn_checks.hpp"

#include "vision/common/rotation.hpp"
#include "vision/model/surface_grid.hpp"

#include <cmath>
#include <utility>

namespace mfcd::vision::detail {

// A turn that moves at most this share of the part's edge points off its surface is a
// near-symmetry: the two poses are compared on the points of the feature that breaks it, as well
// as apart in the image. The image distance alone also counts points the two poses' template
// views disagree on only because the views are sampled apart, which say nothing about the turn.
// The breaker's half turn about z moves 5 % of its points (the toggle) and the wheel's 10 %;
// turned face down, the ellipse moves 67 % and the diamond 84 %. Measured on the three dev sets
// (mfc-sim seeds 7, 13, 19; 283 trials): 90 failures with the image distance alone, 88 with the
// feature's points for near-symmetries (breaker 10 -> 8), 89 when the feature's points replace the
// image distance, 91 when they replace it for every turn (the ellipse turned face down 3 more).
constexpr double kNearSymmetryShare = 0.25;

std::vector<PoseTurn> turned_over(const TemplateDatabase& db) {
  const PartSymmetry& sym = db.symmetry;
  const cv::Matx33d rx(1, 0, 0, 0, -1, 0, 0, 0, -1), ry(-1, 0, 0, 0, 1, 0, 0, 0, -1), rz(-1, 0, 0, 0, -1, 0, 0, 0, 1);
  const bool half_turn_z = sym.kind == PartSymmetry::Kind::continuous_z ||
                           (sym.kind == PartSymmetry::Kind::discrete_z && sym.order % 2 == 0);
  // With the half turn about z a symmetry, the turn about y is the one about x followed by it.
  std::vector<PoseTurn> out;
  const SurfaceGrid surface = part_surface(db);
  for (const cv::Matx33d& S : half_turn_z ? std::vector<cv::Matx33d>{rx} : std::vector<cv::Matx33d>{rx, ry, rz}) {
    PoseTurn& t = out.emplace_back();
    t.S = S;
    t.pivot_mm = db.center_mm;
    double share = 1;
    auto flags = asymmetric_points(db, surface, S, &share);
    if (share <= kNearSymmetryShare) t.differs = std::move(flags);
  }
  return out;
}

// Phase turns: a part with an N-fold symmetry about z (N >= 3) has flutes or spokes, and a fit can
// settle with each flute's flank on its neighbour's opposite flank: the knob's 10 flutes are ~22
// degrees wide in a 36 degree period, and fits from 5-9 degrees off the truth converge to it,
// while from 14-18 degrees off they converge to +-14.5 degrees, where the flanks (edges of the
// same orientation) all find edges and only the flutes' bottoms do not. The fit score alone
// prefers that twin in clutter (measured: 0.26 against 0.31 for a fully visible knob); the
// points where the two differ do not (TemplatePoseFit::compare). Turning by +-0.4 of the period
// starts the fit in the other basin from either twin. The part's symmetry decides, not the views'
// fold: the knob's views are folded 2-fold by its pointer groove (db.views_symmetry), its flutes
// still make it 10-fold.
constexpr double kPhaseTurnShare = 0.4;

std::vector<PoseTurn> phase_turns(const TemplateDatabase& db) {
  const PartSymmetry& sym = db.symmetry;
  std::vector<PoseTurn> out;
  if (sym.kind != PartSymmetry::Kind::discrete_z || sym.order < 3) return out;
  for (const double sign : {1.0, -1.0}) {
    PoseTurn& t = out.emplace_back();
    t.S = rotation_about_z(sign * kPhaseTurnShare * 2 * CV_PI / sym.order);
  }
  return out;
}

// Plate turns: a part with a 2-fold symmetry about z (the diamond, the ellipse, the T-nut) seen on
// edge or steeply tilted shows an outline that changes little when it turns about its own z axis,
// and fits from the search's hypotheses stop 10-25 degrees off, on the flank of the truth's basin:
// in the capped set's scene 7 image 1 an ellipse on edge fitted 24.5 degrees off scores 0.554, the
// fit from the truth 0.560. Fits started +-15 degrees about z reach the truth's basin. The points
// where the two poses differ are mostly those of two template views a few degrees apart, which
// say nothing (judged by compare: 5 correct plates turned wrong, none fixed, on five sets), so
// the turned fit is taken when its rank is higher, and only for hypotheses the cell would pick
// (rank at least config/cell.yaml's min_score 0.1): below that, a higher rank is noise (4 fixed and
// 4 broken without it, all the broken ranked below 0.09).
constexpr double kPlateTurnDeg = 15;

std::vector<PoseTurn> plate_turns(const TemplateDatabase& db) {
  const PartSymmetry& sym = db.symmetry;
  std::vector<PoseTurn> out;
  if (sym.kind != PartSymmetry::Kind::discrete_z || sym.order != 2) return out;
  for (const double sign : {1.0, -1.0}) {
    PoseTurn& t = out.emplace_back();
    t.S = rotation_about_z(sign * kPlateTurnDeg * CV_PI / 180);
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
