#pragma once
// Cycle accounting on the main thread: counters (cycles, overruns, degraded, errors, detections,
// picks) and the cycle times of the last kWindow cycles for percentiles. add() does not allocate.
#include <array>
#include <cstdint>

#include <nlohmann/json.hpp>

#include "daemon/cycle.hpp"

namespace mfcd::daemon {

class CycleStats {
 public:
  static constexpr std::size_t kWindow = 1024;

  // Returns true when the cycle overran the budget (trigger to result > budget_ms).
  bool add(const CycleResult& r, int budget_ms) noexcept;
  // What the robot reported of a pick (motion::reg::PickOutcome, 1..5), and fall-back picks
  // published by NEXT.
  void add_pick_result(std::uint16_t outcome) noexcept;
  void add_next_pick() noexcept { ++next_picks_; }
  std::uint64_t pick_results(std::uint16_t outcome) const {
    return outcome < pick_results_.size() ? pick_results_[outcome] : 0;
  }

  std::uint64_t cycles() const { return cycles_; }
  std::uint64_t overruns() const { return overruns_; }
  std::uint64_t degraded() const { return degraded_; }
  std::uint64_t errors() const { return errors_; }
  std::uint64_t empty() const { return empty_; }
  std::uint64_t detections() const { return detections_; }
  std::uint64_t picks() const { return picks_; }

  // Nearest-rank percentile (p in 0..100) of the total cycle time over the window; 0 when empty.
  double percentile_ms(double p) const;
  // The same for one stage: "capture", "vision" or "total".
  double percentile_ms(const char* stage, double p) const;
  nlohmann::json to_json() const;

 private:
  struct Sample {
    float total, capture, vision;
  };
  std::array<Sample, kWindow> window_{};
  std::size_t count_ = 0;  // samples in window (<= kWindow)
  std::size_t next_ = 0;
  std::uint64_t cycles_ = 0, overruns_ = 0, degraded_ = 0, errors_ = 0, empty_ = 0, detections_ = 0, picks_ = 0;
  double max_ms_ = 0, sum_ms_ = 0;
  std::array<std::uint64_t, 6> pick_results_{};  // by PickOutcome; [0] unused
  std::uint64_t next_picks_ = 0;
};

}  // namespace mfcd::daemon
