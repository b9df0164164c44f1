#include "motion/pick_choice.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <vector>

using namespace mfcd::motion;

namespace {
// Slow twin: compute every utility, stable-sort indices by it.
std::vector<std::uint16_t> reference_rank(const std::vector<PickCandidate>& cands, const PickChoiceConfig& cfg) {
  std::vector<std::pair<float, std::uint16_t>> scored;
  for (std::size_t i = 0; i < cands.size(); ++i) {
    const PickCandidate& c = cands[i];
    if (std::isnan(c.score) || std::isnan(c.height_mm) || std::isnan(c.grasp_visibility) || std::isinf(c.height_mm) ||
        c.score < cfg.min_score || c.grasp_visibility < cfg.min_grasp_visibility || (c.ambiguous && cfg.skip_ambiguous))
      continue;
    float h = c.height_mm / cfg.height_scale_mm;
    h = h < 0 ? 0 : (h > 1 ? 1 : h);
    const float g = c.grasp_visibility > 1 ? 1 : c.grasp_visibility;
    scored.push_back(
        {cfg.weight_score * c.score + cfg.weight_height * h + cfg.weight_grasp * g, static_cast<std::uint16_t>(i)});
  }
  std::stable_sort(scored.begin(), scored.end(), [](auto& a, auto& b) { return a.first > b.first; });
  std::vector<std::uint16_t> out;
  for (auto& s : scored) out.push_back(s.second);
  return out;
}
}  // namespace

TEST(PickChoice, HigherPartWinsWhenScoresTie) {
  const PickCandidate c[] = {{0.9f, 20.0f, 1.0f}, {0.9f, 120.0f, 1.0f}, {0.9f, 60.0f, 1.0f}};
  EXPECT_EQ(choose_pick(c, PickChoiceConfig{}), 1u);
}

TEST(PickChoice, HiddenGraspFeatureLoses) {
  PickChoiceConfig cfg;
  cfg.weight_grasp = 2.0f;
  const PickCandidate c[] = {{0.95f, 100.0f, 0.1f}, {0.85f, 100.0f, 0.9f}};
  EXPECT_EQ(choose_pick(c, cfg), 1u);
  cfg.weight_grasp = 0.0f;
  EXPECT_EQ(choose_pick(c, cfg), 0u);
  cfg.min_grasp_visibility = 0.5f;
  EXPECT_EQ(choose_pick(c, cfg), 1u) << "below the visibility floor is never picked";
}

TEST(PickChoice, NothingEligible) {
  const PickCandidate c[] = {{0.05f, 100.0f, 1.0f}, {std::nanf(""), 100.0f, 1.0f}};
  EXPECT_FALSE(choose_pick(c, PickChoiceConfig{}));
  EXPECT_FALSE(choose_pick(std::span<const PickCandidate>{}, PickChoiceConfig{}));
  std::uint16_t order[4];
  EXPECT_EQ(rank_picks(c, PickChoiceConfig{}, order), 0u);
}

TEST(PickChoice, AmbiguousCandidateIsPassedOver) {
  // The better candidate's pose cannot be told from another: the cell takes the next one.
  PickCandidate c[] = {{0.9f, 100.0f, 1.0f}, {0.6f, 100.0f, 1.0f}};
  c[0].ambiguous = true;
  PickChoiceConfig cfg;
  EXPECT_EQ(choose_pick(c, cfg), 1u);
  std::uint16_t order[2];
  ASSERT_EQ(rank_picks(c, cfg, order), 1u);
  EXPECT_EQ(order[0], 1u);
  cfg.skip_ambiguous = false;
  EXPECT_EQ(choose_pick(c, cfg), 0u);
  c[1].ambiguous = true;
  cfg.skip_ambiguous = true;
  EXPECT_FALSE(choose_pick(c, cfg)) << "nothing unambiguous: no pick";
}

TEST(PickChoice, TiesGoToTheLowerIndex) {
  const PickCandidate c[] = {{0.7f, 50.0f, 0.5f}, {0.7f, 50.0f, 0.5f}};
  EXPECT_EQ(choose_pick(c, PickChoiceConfig{}), 0u);
}

TEST(PickChoice, MatchesReferenceRankingOnRandomCandidates) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f), height(-50.0f, 400.0f), weight(0.0f, 2.0f);
  std::uniform_int_distribution<int> count(0, 40), coarse(0, 4);
  for (int trial = 0; trial < 5000; ++trial) {
    PickChoiceConfig cfg;
    cfg.weight_score = weight(rng);
    cfg.weight_height = weight(rng);
    cfg.weight_grasp = weight(rng);
    cfg.min_score = unit(rng) * 0.6f;
    cfg.skip_ambiguous = unit(rng) < 0.5f;
    ASSERT_TRUE(cfg.validate().empty());
    std::vector<PickCandidate> cands(count(rng));
    for (auto& c : cands) {
      // Coarse values make ties frequent, to test the tie rule too.
      c = {coarse(rng) / 4.0f, coarse(rng) * 50.0f, coarse(rng) / 4.0f};
      if (unit(rng) < 0.5f) c = {unit(rng), height(rng), unit(rng)};
      if (unit(rng) < 0.02f) c.height_mm = std::nanf("");
      c.ambiguous = unit(rng) < 0.2f;
    }
    const auto want = reference_rank(cands, cfg);
    const auto best = choose_pick(cands, cfg);
    ASSERT_EQ(best.has_value(), !want.empty());
    if (best) {
      ASSERT_EQ(*best, want.front());
    }
    std::vector<std::uint16_t> order(cands.size());
    order.resize(rank_picks(cands, cfg, order));
    ASSERT_EQ(order, want);
    // A short output buffer keeps the best ones.
    std::uint16_t top3[3];
    const std::size_t n = rank_picks(cands, cfg, top3);
    ASSERT_EQ(n, std::min<std::size_t>(3, want.size()));
    for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(top3[i], want[i]);
  }
}

TEST(PickChoice, ConfigValidationNamesTheKey) {
  PickChoiceConfig cfg;
  cfg.weight_height = -1.0f;
  EXPECT_NE(cfg.validate().find("weight_height"), std::string::npos);
  cfg = {};
  cfg.height_scale_mm = 0.0f;
  EXPECT_NE(cfg.validate().find("height_scale_mm"), std::string::npos);
  cfg = {};
  cfg.min_score = 1.5f;
  EXPECT_NE(cfg.validate().find("min_score"), std::string::npos);
}
