#pragma once
// The confidence model's weights as tools/bench/fit_confidence.py fitted them (do not edit; run
// it again): generalize-dev.json, 305 candidates (36 right), held-out AUC
// 0.882, expected calibration error 0.041 (docs/tuning-log.md).
#include "vision/pipeline/confidence.hpp"

namespace mfcd::vision {

inline constexpr ConfidenceModel kFittedConfidence{
    .bias = -0.695924,
    .fit_rank = 2.15533,
    .coverage = -0.856042,
    .inlier_fraction = 1.41568,
    .fit_cost_px = -0.773913,
    .has_alternative = -0.769977,
    .alternative_margin = -0.034468,
    .alternative_support = 1.22357,
};

}  // namespace mfcd::vision
