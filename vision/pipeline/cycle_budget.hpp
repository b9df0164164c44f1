#pragma once
// The deadline rules of a pick cycle in one place. The search stops early enough to leave the
// hypothesis fit the time it took last cycle; the optional stages (escalation's wide search, later
// search rounds) start only when the time left covers what they took the last time they ran.
// Every estimate is what this pipeline measured on this machine, so nothing here is tuned per
// machine. No allocation; one per pipeline, used by the thread that runs its cycles.

#include <chrono>

namespace mfcd::vision::detail {

class CycleBudget {
 public:
  using Clock = std::chrono::steady_clock;
  enum class Optional { escalation, round };

  // Before the first cycle the fit of a hypothesis on `threads` threads is estimated at 2 ms of
  // one thread.
  explicit CycleBudget(int threads);

  void start(Clock::time_point deadline) { deadline_ = deadline; }
  Clock::time_point deadline() const { return deadline_; }
  // Called when the search starts: the search's own deadline, which leaves the fit of `wanted`
  // hypotheses 1.5 times its estimate and never more than half the time left (the search always
  // gets the other half).
  Clock::time_point search_deadline(int wanted) const;
  // Whether an optional stage, started now, would end before the deadline if it takes what it
  // took last time (0 before it first ran: it runs whenever the deadline has not passed).
  bool leaves_time_for(Optional stage) const;

  // The fit of `fitted` hypotheses took `ms` (a cycle's fit cut short says as much per hypothesis
  // as a whole one).
  void record_fit(double ms, int fitted);
  void record(Optional stage, double ms) { (stage == Optional::escalation ? escalation_ms_ : round_ms_) = ms; }

 private:
  Clock::time_point deadline_{};
  double fit_ms_each_ = 0, escalation_ms_ = 0, round_ms_ = 0;
};

double ms_between(CycleBudget::Clock::time_point a, CycleBudget::Clock::time_point b);

}  // namespace mfcd::vision::detail
