#include "vision/pipeline/confidence.hpp"

#include <cmath>

namespace mfcd::vision {

double ConfidenceModel::logit(const PoseEvidence& e) const {
  return bias + fit_rank * e.fit_rank + coverage * e.coverage + inlier_fraction * e.inlier_fraction +
         fit_cost_px * e.fit_cost_px + has_alternative * (e.has_alternative ? 1.0 : 0.0) +
         alternative_margin * e.alternative_margin + alternative_support * e.alternative_support;
}

namespace {

double logistic(double z) {
  // Either branch keeps exp() from overflowing for a large |z|.
  if (z >= 0) return 1.0 / (1.0 + std::exp(-z));
  const double ez = std::exp(z);
  return ez / (1.0 + ez);
}

}  // namespace

double ConfidenceModel::probability(const PoseEvidence& e) const { return logistic(logit(e)); }

double FusedConfidenceModel::logit(const FusedEvidence& e) const {
  return bias + rank_first * e.rank_first + rank_second * e.rank_second +
         has_alternative * (e.has_alternative ? 1.0 : 0.0) + alternative_margin * e.alternative_margin;
}

double FusedConfidenceModel::probability(const FusedEvidence& e) const { return logistic(logit(e)); }

}  // namespace mfcd::vision
