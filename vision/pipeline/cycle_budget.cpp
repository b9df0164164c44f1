#include "vision/pipeline/cycle_budget.hpp"

#include <algorithm>

namespace mfcd::vision::detail {

namespace {

CycleBudget::Clock::duration milliseconds(double ms) {
  return std::chrono::duration_cast<CycleBudget::Clock::duration>(std::chrono::duration<double, std::milli>(ms));
}

}  // namespace

double ms_between(CycleBudget::Clock::time_point a, CycleBudget::Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

CycleBudget::CycleBudget(int threads) : fit_ms_each_(2.0 / std::max(1, threads)) {}

CycleBudget::Clock::time_point CycleBudget::search_deadline(int wanted) const {
  const double left_ms = std::max(0.0, ms_between(Clock::now(), deadline_));
  return deadline_ - milliseconds(std::min(1.5 * fit_ms_each_ * wanted, 0.5 * left_ms));
}

bool CycleBudget::leaves_time_for(Optional stage) const {
  const double ms = stage == Optional::escalation ? escalation_ms_ : round_ms_;
  return Clock::now() + milliseconds(ms) <= deadline_;
}

void CycleBudget::record_fit(double ms, int fitted) {
  if (fitted > 0) fit_ms_each_ = ms / fitted;
}

}  // namespace mfcd::vision::detail
