#include "motion/pick_choice.hpp"

#include <algorithm>
#include <cmath>

namespace mfcd::motion {

std::string PickChoiceConfig::validate() const {
  const auto bad_weight = [](float w) { return !std::isfinite(w) || w < 0.0f; };
  if (bad_weight(weight_score)) return "pick weight_score must be a finite number >= 0";
  if (bad_weight(weight_height)) return "pick weight_height must be a finite number >= 0";
  if (bad_weight(weight_grasp)) return "pick weight_grasp must be a finite number >= 0";
  if (!(height_scale_mm > 0.0f) || !std::isfinite(height_scale_mm)) return "pick height_scale_mm must be > 0";
  if (!(min_score >= 0.0f && min_score <= 1.0f)) return "pick min_score must be within 0..1";
  if (!(min_grasp_visibility >= 0.0f && min_grasp_visibility <= 1.0f))
    return "pick min_grasp_visibility must be within 0..1";
  return {};
}

std::optional<float> pick_utility(const PickCandidate& c, const PickChoiceConfig& config) noexcept {
  if (!std::isfinite(c.score) || !std::isfinite(c.height_mm) || !std::isfinite(c.grasp_visibility)) return std::nullopt;
  if (c.score < config.min_score || c.grasp_visibility < config.min_grasp_visibility) return std::nullopt;
  if (c.ambiguous && config.skip_ambiguous) return std::nullopt;
  const float height = std::clamp(c.height_mm / config.height_scale_mm, 0.0f, 1.0f);
  const float grasp = std::clamp(c.grasp_visibility, 0.0f, 1.0f);
  return config.weight_score * c.score + config.weight_height * height + config.weight_grasp * grasp;
}

std::optional<std::size_t> choose_pick(std::span<const PickCandidate> candidates,
                                       const PickChoiceConfig& config) noexcept {
  std::optional<std::size_t> best;
  float best_utility = 0.0f;
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    const auto u = pick_utility(candidates[i], config);
    if (u && (!best || *u > best_utility)) {
      best = i;
      best_utility = *u;
    }
  }
  return best;
}

std::size_t rank_picks(std::span<const PickCandidate> candidates, const PickChoiceConfig& config,
                       std::span<std::uint16_t> order) noexcept {
  // Insertion sort into the caller's buffer: candidate lists are tens long, and this keeps
  // the call allocation-free and stable.
  std::size_t n = 0;
  for (std::size_t i = 0; i < candidates.size() && i <= 0xffff; ++i) {
    const auto u = pick_utility(candidates[i], config);
    if (!u) continue;
    std::size_t at = std::min(n, order.size());
    while (at > 0 && *pick_utility(candidates[order[at - 1]], config) < *u) --at;
    if (at >= order.size()) continue;  // below everything already kept and no room
    const std::size_t last = std::min(n, order.size() - 1);
    for (std::size_t k = last; k > at; --k) order[k] = order[k - 1];
    order[at] = static_cast<std::uint16_t>(i);
    n = std::min(n + 1, order.size());
  }
  return n;
}

}  // namespace mfcd::motion
