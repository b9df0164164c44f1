#include "vision/pipeline/confidence.hpp"
#include "vision/pipeline/bin_picking_pipeline.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

using namespace mfcd::vision;

namespace {

// Slow twin: the logistic function written out, in long double.
double reference_probability(const ConfidenceModel& m, const PoseEvidence& e) {
  const long double z = static_cast<long double>(m.bias) + m.fit_rank * e.fit_rank + m.coverage * e.coverage +
                        m.inlier_fraction * e.inlier_fraction + m.fit_cost_px * e.fit_cost_px +
                        (e.has_alternative ? m.has_alternative : 0.0) + m.alternative_margin * e.alternative_margin +
                        m.alternative_support * e.alternative_support;
  return static_cast<double>(1.0L / (1.0L + std::exp(-z)));
}

}  // namespace

TEST(Confidence, ProbabilityIsTheLogisticOfTheWeightedMeasures) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> w(-20, 20), x(-1, 2);
  for (int trial = 0; trial < 2000; ++trial) {
    const ConfidenceModel m{w(rng), w(rng), w(rng), w(rng), w(rng), w(rng), w(rng), w(rng)};
    PoseEvidence e;
    e.fit_rank = x(rng), e.coverage = x(rng), e.inlier_fraction = x(rng), e.fit_cost_px = 4 * x(rng);
    e.has_alternative = x(rng) > 0.5, e.alternative_margin = x(rng), e.alternative_support = x(rng);
    const double p = m.probability(e);
    ASSERT_GE(p, 0.0);
    ASSERT_LE(p, 1.0);
    ASSERT_NEAR(p, reference_probability(m, e), 1e-12) << "trial " << trial;
  }
}

TEST(Confidence, FusedProbabilityIsTheLogisticOfTheWeightedMeasures) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> w(-20, 20), x(-1, 2);
  for (int trial = 0; trial < 2000; ++trial) {
    const FusedConfidenceModel m{w(rng), w(rng), w(rng), w(rng), w(rng)};
    const FusedEvidence e{x(rng), x(rng), x(rng) > 0.5, x(rng)};
    // Slow twin, in long double.
    const long double z = static_cast<long double>(m.bias) + m.rank_first * e.rank_first +
                          m.rank_second * e.rank_second + (e.has_alternative ? m.has_alternative : 0.0) +
                          m.alternative_margin * e.alternative_margin;
    ASSERT_NEAR(m.probability(e), static_cast<double>(1.0L / (1.0L + std::exp(-z))), 1e-12) << "trial " << trial;
  }
  const FusedConfidenceModel huge{0, 1e6, 0, 0, 0};
  EXPECT_EQ(huge.probability({1, 0, false, 0}), 1.0);
  EXPECT_EQ(huge.probability({-1, 0, false, 0}), 0.0);
}

TEST(Confidence, ExtremeLogitsStayFinite) {
  ConfidenceModel m;
  m.fit_rank = 1e6;
  PoseEvidence e;
  e.fit_rank = 1;
  EXPECT_EQ(m.probability(e), 1.0);
  e.fit_rank = -1;
  EXPECT_EQ(m.probability(e), 0.0);
  EXPECT_FALSE(std::isnan(m.probability(e)));
}

TEST(Confidence, EvidenceOfACandidateWithoutAlternativeHasNoMargin) {
  PoseCandidate c;
  c.fit_rank = 0.4, c.coverage = 0.7, c.inlier_fraction = 0.8, c.fit_cost_px = 1.2;
  c.alternative_rank = 0.3, c.alternative_support = 0.2;  // left from nothing: not an alternative
  PoseEvidence e = c.evidence();
  EXPECT_FALSE(e.has_alternative);
  EXPECT_EQ(e.alternative_margin, 0.0);
  EXPECT_EQ(e.alternative_support, 0.0);
  EXPECT_EQ(e.fit_rank, 0.4);
  EXPECT_EQ(e.coverage, 0.7);
  EXPECT_EQ(e.inlier_fraction, 0.8);
  EXPECT_EQ(e.fit_cost_px, 1.2);
  c.has_alternative = true;
  e = c.evidence();
  EXPECT_TRUE(e.has_alternative);
  EXPECT_NEAR(e.alternative_margin, 0.1, 1e-12);
  EXPECT_EQ(e.alternative_support, 0.2);
}

TEST(Confidence, FittedModelPrefersTheBetterMeasuredPose) {
  // Whatever the fit on the bench's dev split gave, a pose that fits better and is told apart
  // from its alternative must not be less probable than one that fits worse and is not.
  const ConfidenceModel& m = kFittedConfidence;
  PoseEvidence good, poor;
  good.fit_rank = 0.5, good.coverage = 0.8, good.inlier_fraction = 0.8, good.fit_cost_px = 0.8;
  good.has_alternative = true, good.alternative_margin = 0.2, good.alternative_support = 0.4;
  poor.fit_rank = 0.05, poor.coverage = 0.3, poor.inlier_fraction = 0.3, poor.fit_cost_px = 2.5;
  poor.has_alternative = true, poor.alternative_margin = 0.0, poor.alternative_support = -0.2;
  EXPECT_GT(m.probability(good), m.probability(poor));
}
