// The cycle line's journal fields and the line itself (declared in daemon/journal_log.hpp): apart
// from the sink, so that what only needs the sink (the control socket's fuzz harness) does not
// bring the cycle's types and the HAL with it.
#include <cstdio>

#include "daemon/cycle.hpp"
#include "daemon/journal_log.hpp"
#include "daemon/log.hpp"

namespace mfcd::daemon {

void cycle_journal_fields(const CycleResult& r, JournalFields& out) {
  out.clear();
  out.addf("MFCD_CYCLE", "%llu", static_cast<unsigned long long>(r.request.cycle_id));
  out.addf("MFCD_JOB_ID", "%u", static_cast<unsigned>(r.request.job_id));
  out.addf("MFCD_ERROR_CODE", "%u", static_cast<unsigned>(r.error));
  // The same condition as the pick line of log_cycle_result: an error line has no pick fields.
  if (r.error == CycleError::None && r.chosen >= 0 && r.chosen < CycleResult::kMaxCandidates) {
    const CandidateOut& c = r.candidates[static_cast<std::size_t>(r.chosen)];
    out.addf("MFCD_PART", "%d", c.obj_id);
    out.addf("MFCD_SCORE", "%.3f", static_cast<double>(c.score));
  }
}

void log_cycle_result(const CycleResult& r) {
  // The texts are the ones Daemon::on_result always wrote; the plain path prints them unchanged.
  char line[1024];
  LogLevel level;
  const unsigned long long id = r.request.cycle_id;
  if (r.error != CycleError::None) {
    level = LogLevel::Error;
    std::snprintf(line, sizeof line, "cycle %llu (%s job %u recipe %u): error %u: %s", id, to_string(r.request.origin),
                  r.request.job_id, r.request.recipe_id, static_cast<unsigned>(r.error), r.message);
  } else if (r.chosen >= 0) {
    level = LogLevel::Info;
    const CandidateOut& c = r.candidates[static_cast<std::size_t>(r.chosen)];
    const auto& p = c.base;
    std::snprintf(line, sizeof line,
                  "cycle %llu (%s job %u recipe %u): pick obj %d at %.1f %.1f %.1f / %.1f %.1f %.1f score %.3f, %d "
                  "found, %.0f ms%s",
                  id, to_string(r.request.origin), r.request.job_id, r.request.recipe_id, c.obj_id, p.x_mm, p.y_mm,
                  p.z_mm, p.rx_deg, p.ry_deg, p.rz_deg, c.score, r.candidate_count, r.total_ms,
                  r.degraded ? " (degraded)" : "");
  } else {
    level = LogLevel::Notice;
    std::snprintf(line, sizeof line, "cycle %llu (%s job %u recipe %u): no pick, %d found, %.0f ms", id,
                  to_string(r.request.origin), r.request.job_id, r.request.recipe_id, r.candidate_count, r.total_ms);
  }
  if (!log_enabled(level)) return;
  JournalFields fields;
  if (log_to_journal()) cycle_journal_fields(r, fields);  // the plain path does not use them
  log_structured(level, fields, line);
}

}  // namespace mfcd::daemon
