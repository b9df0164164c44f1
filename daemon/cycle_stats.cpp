#include "daemon/cycle_stats.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

namespace mfcd::daemon {

bool CycleStats::add(const CycleResult& r, int budget_ms) noexcept {
  ++cycles_;
  const bool overrun = r.total_ms > budget_ms;
  overruns_ += overrun;
  degraded_ += r.degraded;
  errors_ += r.error != CycleError::None;
  empty_ += r.error == CycleError::None && r.candidate_count == 0;
  detections_ += static_cast<std::uint64_t>(r.candidate_count);
  picks_ += r.chosen >= 0;
  window_[next_] = {static_cast<float>(r.total_ms), static_cast<float>(r.capture_ms), static_cast<float>(r.vision_ms)};
  next_ = (next_ + 1) % kWindow;
  count_ = std::min(count_ + 1, kWindow);
  max_ms_ = std::max(max_ms_, r.total_ms);
  sum_ms_ += r.total_ms;
  return overrun;
}

double CycleStats::percentile_ms(double p) const { return percentile_ms("total", p); }

double CycleStats::percentile_ms(const char* stage, double p) const {
  if (count_ == 0) return 0;
  std::vector<float> v(count_);
  for (std::size_t i = 0; i < count_; ++i) {
    const Sample& s = window_[i];
    v[i] = std::strcmp(stage, "capture") == 0 ? s.capture : std::strcmp(stage, "vision") == 0 ? s.vision : s.total;
  }
  std::sort(v.begin(), v.end());
  // Nearest rank: the smallest value with at least p % of the samples at or below it.
  const double rank = std::ceil(p / 100.0 * static_cast<double>(count_));
  const std::size_t index = rank < 1 ? 0 : std::min(count_ - 1, static_cast<std::size_t>(rank) - 1);
  return v[index];
}

void CycleStats::add_pick_result(std::uint16_t outcome) noexcept {
  if (outcome >= 1 && outcome < pick_results_.size()) ++pick_results_[outcome];
}

nlohmann::json CycleStats::to_json() const {
  nlohmann::json j = {{"cycles", cycles_},     {"overruns", overruns_},
                      {"degraded", degraded_}, {"errors", errors_},
                      {"empty", empty_},       {"detections", detections_},
                      {"picks", picks_},       {"window", count_},
                      {"max_ms", max_ms_},     {"mean_ms", cycles_ ? sum_ms_ / static_cast<double>(cycles_) : 0.0}};
  // The robot's reports (Modbus PICK_RESULT): every outcome, and the share of reported picks that failed.
  std::uint64_t reported = 0;
  for (std::size_t k = 1; k < pick_results_.size(); ++k) reported += pick_results_[k];
  j["pick_results"] = {
      {"ok", pick_results_[1]},
      {"missed", pick_results_[2]},
      {"unreachable", pick_results_[3]},
      {"collision", pick_results_[4]},
      {"dropped", pick_results_[5]},
      {"reported", reported},
      {"failed_share",
       reported ? static_cast<double>(reported - pick_results_[1]) / static_cast<double>(reported) : 0.0}};
  j["next_picks"] = next_picks_;
  for (const char* stage : {"total", "capture", "vision"}) {
    j["percentiles_ms"][stage] = {{"p50", percentile_ms(stage, 50)},
                                  {"p90", percentile_ms(stage, 90)},
                                  {"p99", percentile_ms(stage, 99)},
                                  {"max", percentile_ms(stage, 100)}};
  }
  return j;
}

}  // namespace mfcd::daemon
