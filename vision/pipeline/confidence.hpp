#pragma once
// A pick candidate's confidence: the estimated probability that its pose is right, i.e. within
// 5 mm and 10 degrees of a true pose of its part (symmetry-aware, the evaluation's criterion).
// A logistic model of what the cycle measured of the candidate, with no term that knows the
// part: the fit's own measures and how clearly the edges told the pose from its best distinct
// alternative at the same place. Its weights are fitted on the generalization bench's dev split
// (tools/bench/fit_confidence.py writes confidence_fitted.hpp); a cell may set its own through
// the parameter table's confidence_* keys.

namespace mfcd::vision {

// What "right" means above, and so which other fitted pose of a part at the same place is another
// answer rather than the same one (PoseCandidate's alternative): its centre this far or more, or
// its orientation this far or more over the part's symmetries.
inline constexpr double kDistinctPositionMm = 5;
inline constexpr double kDistinctRotationDeg = 10;

// What the cycle measured of one candidate (PoseCandidate's fields of the same names).
struct PoseEvidence {
  double fit_rank = 0;             // fit score less the unexplained-edge penalty, about 0..1
  double coverage = 0;             // share of image edges inside the outline that the pose explains
  double inlier_fraction = 0;      // share of the view's points within the fit's inlier cost
  double fit_cost_px = 0;          // the fit's mean directional cost, px (truncated at its gate)
  bool has_alternative = false;    // a distinct other pose was fitted at the place
  double alternative_margin = 0;   // fit_rank less the alternative's; 0 without one
  double alternative_support = 0;  // on the differing points: share on edges, this less the other's
};

// logit = bias + sum of weight x measure; probability = 1 / (1 + exp(-logit)). The weights'
// names are the measures'.
struct ConfidenceModel {
  double bias = 0;
  double fit_rank = 0;
  double coverage = 0;
  double inlier_fraction = 0;
  double fit_cost_px = 0;  // per px
  double has_alternative = 0;
  double alternative_margin = 0;
  double alternative_support = 0;

  double logit(const PoseEvidence& e) const;
  double probability(const PoseEvidence& e) const;
};

// What a second look measured of one fused candidate (SecondLookCandidate's fields).
struct FusedEvidence {
  double rank_first = 0;          // fitted rank in the first image, about 0..1
  double rank_second = 0;         // fitted rank in the second image
  bool has_alternative = false;   // a distinct other pose of the part was fitted at its place
  double alternative_margin = 0;  // rank sum less the alternative's; 0 without one
};

// The fused candidates' confidence: the same logistic form over FusedEvidence. A model of its
// own because the fused measures are not the single view's (two images, no edge-support terms).
struct FusedConfidenceModel {
  double bias = 0;
  double rank_first = 0;
  double rank_second = 0;
  double has_alternative = 0;
  double alternative_margin = 0;

  double logit(const FusedEvidence& e) const;
  double probability(const FusedEvidence& e) const;
};

}  // namespace mfcd::vision
