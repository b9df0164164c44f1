#pragma once
// The confidence model's weights as tools/bench/fit_confidence.py fitted them (do not edit; run
// it again): generalize-dev.json, 305 candidates (36 right), held-out AUC
// 0.907, expected calibration error 0.050 (docs/tuning-log.md).
#include "vision/pipeline/confidence.hpp"

namespace mfcd::vision {

inline constexpr ConfidenceModel kFittedConfidence{
    .bias = -1.15177,
    .fit_rank = 2.14819,
    .coverage = -0.825194,
    .inlier_fraction = 1.53533,
    .fit_cost_px = -0.985866,
    .has_alternative = 0.310584,
    .alternative_margin = 0.379986,
    .alternative_support = 1.54221,
};

}  // namespace mfcd::vision
