#pragma once
// The pipeline's turn checks: the alternative poses its leading hypotheses are compared with
// (the part's turns found from its mesh, a declared 2-fold plate turned or spun as seen on edge),
// made once per part type from its template database, and the rule that takes a turned
// pose over the hypothesis (turn_is_better). The constants below are the checks' thresholds;
// docs/tuning-log.md and docs/pose.md say how each was measured.

#include "vision/pose/template_pose_fit.hpp"
#include "vision/templates/template_database.hpp"

#include <opencv2/core.hpp>

#include <cstdint>
#include <optional>
#include <vector>

namespace mfcd::vision::detail {

// The turns the fit checks its best poses against, found from the mesh (mesh_turns): turned over
// about its principal axes, its near-symmetries, and phase turns of its N-fold axes (N >= 3).
struct PoseTurn {
  cv::Matx33d S;
  // The point of the model the turn is about (on its axis).
  cv::Vec3d pivot_mm{0, 0, 0};
  // A near-symmetry (few points flagged): per view, per point, whether the point belongs to the
  // feature that breaks it (asymmetric_points); the check then compares only those. Empty for
  // a turn that changes most of the part's edges (a plate turned face down). `differs` is for
  // the pose (points X whose S^-1 X is off the surface: the twin has no surface there) and
  // `differs_turned` for the turned pose (points Y whose S Y is off it); empty when S is its own
  // inverse (a half turn), where the two are the same.
  std::vector<std::vector<uint8_t>> differs, differs_turned;
  const std::vector<uint8_t>* flags_of_pose(int view) const {
    return differs.empty() ? nullptr : &differs[static_cast<size_t>(view)];
  }
  const std::vector<uint8_t>* flags_of_turned(int view) const {
    const auto& d = differs_turned.empty() ? differs : differs_turned;
    return d.empty() ? nullptr : &d[static_cast<size_t>(view)];
  }
  // Judged by the fitted rank instead of TemplatePoseFit::compare (plate_turns).
  bool by_rank = false;
  // A near-symmetry lands its twin on the pose's own edges: the twin is first compared as it is,
  // unfitted, and fitted only when that comparison favours it (a gear's N - 1 tooth turns cost N - 1
  // comparisons, not N - 1 fits).
  bool screen = false;
};

// The turns of the part found from its mesh alone (vision/model/mesh_turns.hpp), as mfc-teach
// stored them in the database (TemplateDatabase::turns): turned over by 180 degrees about each
// principal axis that is not a symmetry, every turn of a near-symmetry (carrying the points of the
// feature that breaks it, and screened), and +-0.4 of the period about each axis of an N-fold
// symmetry or near-symmetry (N >= 3). The near-symmetries' flagged points (asymmetric_points) are
// made here, at load.
std::vector<PoseTurn> mesh_turns(const TemplateDatabase& db);
// A plate's normal as the mesh says it: the axis of an exactly 2-fold symmetry (db.turns) within
// kPlateAxisMaxDeg of the part's axis of least extent (its smallest principal axis). None: the
// part is no plate with a 2-fold turn about its normal.
std::optional<cv::Vec3d> plate_axis(const TemplateDatabase& db);
// That symmetry itself (its axis and pivot), or null.
const MeshTurn* plate_symmetry(const TemplateDatabase& db);
inline constexpr double kPlateAxisMaxDeg = 10;
// Plate turns' angle, degrees (turn_checks.cpp says why).
inline constexpr double kPlateTurnDeg = 15;
// About a plate axis: +-kPlateTurnDeg, judged by the fitted rank.
std::vector<PoseTurn> plate_turns(const TemplateDatabase& db);

// Plate turns are taken only for hypotheses ranked at least this (below it a higher rank is noise).
inline constexpr double kPlateTurnMinRank = 0.1;

// Turned-over check: the turned pose is considered when its fit scores at least this share of
// the pose's, and taken (turn_is_better) when at least kFlipMinPoints of its points differ from
// the pose's and a larger share of those (by kFlipMargin) lie on image edges than of the pose's
// own differing ones ...
inline constexpr double kFlipMinScoreRatio = 0.6;
inline constexpr int kFlipMinPoints = 6;
inline constexpr double kFlipMargin = 0.2;
// ... or when both have kFlipMinPoints differing and the turned pose's lie nearer edges by this
// much of mean cost (TemplatePoseFit::Difference::cost_b, truncated at 10 px). The breaker's toggle
// fitted from a template view a few degrees off lands 2-5 px beside its edges: 2 of 31 points
// found, against 0 of 34 for the turned twin's toggle over bare bin, yet mean costs of 5.3 and
// 9.5 px ...
inline constexpr double kFlipCostMarginPx = 2;
// ... or when the turned pose hides the feature (at most one point differs: the toggle faces
// away) while the pose shows it where no edge lies near (mean cost at least this): the missing
// edges of a feature the pose says is in view are the evidence. A part lying over the feature
// would bring its own edges near.
inline constexpr int kFlipHiddenMaxPoints = 1;
inline constexpr double kFlipAbsentCostPx = 7;

// Whether the turned pose (b) of a comparison (TemplatePoseFit::compare) beats the hypothesis (a).
bool turn_is_better(const TemplatePoseFit::Difference& d);

// Spin check: a plate with a 2-fold symmetry about its normal (plate_axis) standing on its rim shows a strip from
// above whose length is all that tells its spin about z (its normal), and a wrong spin with a
// compensating distance makes nearly the same strip: on 160 single parts on an empty floor, two
// diamonds on their rim were reported spun 35 and 54 degrees, the truth being a lower-ranked
// hypothesis at the same place. Where the two differ (the wrong spin's ends past the strip's,
// over bare floor) the edges tell them apart, so each of the best kSpinCheckLeaders hypotheses
// of such a part, when seen on edge (its normal at least kSpinCheckMinTiltDeg from the line of
// sight), is compared (TemplatePoseFit::compare, turn_is_better) with every lower-ranked
// rescored hypothesis of the part at its place (fitted centres within kSpinCheckPlace of the
// part's image diameter) whose normal agrees within kSpinCheckMaxAxisDeg and whose spin differs
// by at least kSpinCheckMinSpinDeg. Measured on five sets (docs/pose.md "Spin check"): 246 ->
// 244 failures, 0 broken; asking flat plates too (spin 10 degrees) broke 3.
inline constexpr int kSpinCheckLeaders = 4;
inline constexpr double kSpinCheckMinTiltDeg = 60;
inline constexpr double kSpinCheckMaxAxisDeg = 10;
inline constexpr double kSpinCheckMinSpinDeg = 20;
inline constexpr double kSpinCheckPlace = 0.25;

}  // namespace mfcd::vision::detail
