// Which detected candidate to pick: a weighted utility of match score, height above the bin
// floor (topmost parts are least likely to be trapped) and whether the grasp feature is
// visible. Allocation-free; the daemon calls it once per cycle.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>

namespace mfcd::motion {

struct PickCandidate {
  float score = 0;             // matcher score, 0..1
  float height_mm = 0;         // part origin above the bin floor
  float grasp_visibility = 0;  // fraction of the grasp feature seen, 0..1
  bool ambiguous = false;      // the image does not tell its pose from another (vision::PoseCandidate::ambiguous)
};

struct PickChoiceConfig {
  float weight_score = 1.0f;
  float weight_height = 0.5f;
  float weight_grasp = 0.5f;
  float height_scale_mm = 200.0f;  // height at which the height term saturates at 1 (bin depth)
  float min_score = 0.3f;          // candidates below are never picked (score: the probability that the pose is right)
  float min_grasp_visibility = 0.0f;
  bool skip_ambiguous = true;  // ambiguous candidates are never picked

  // Empty when valid; else names the key and the reason.
  std::string validate() const;
};

// utility = weight_score*score + weight_height*clamp(height/height_scale, 0, 1)
//         + weight_grasp*grasp_visibility; NaN inputs make a candidate ineligible.
std::optional<float> pick_utility(const PickCandidate& c, const PickChoiceConfig& config) noexcept;

// Index of the eligible candidate with the highest utility; ties go to the lower index.
std::optional<std::size_t> choose_pick(std::span<const PickCandidate> candidates,
                                       const PickChoiceConfig& config) noexcept;

// Eligible candidate indices by decreasing utility (stable) into `order`; returns how many
// were written. For fall-back picks when the first choice is unreachable.
std::size_t rank_picks(std::span<const PickCandidate> candidates, const PickChoiceConfig& config,
                       std::span<std::uint16_t> order) noexcept;

}  // namespace mfcd::motion
