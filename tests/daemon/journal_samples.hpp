#pragma once
// The three cycle results the journald tests log (journal_log_test.cpp) and the probe sends
// through a real journald (journal_probe_main.cpp): an error, a pick and a cycle without a pick,
// with the exact result lines Daemon::on_result has always written for them.
#include <cstdint>
#include <string>

#include "daemon/cycle.hpp"

namespace mfcd::daemon::test {

// Cycle `cycle`, job `job`: the camera failed (ERROR_CODE 2). The message holds a newline, as an
// exception's what() may.
inline CycleResult error_result(std::uint64_t cycle, std::uint16_t job) {
  CycleResult r;
  r.request.cycle_id = cycle;
  r.request.job_id = job;
  r.request.recipe_id = 2;
  r.request.origin = CycleOrigin::Plc;
  r.error = CycleError::Capture;
  copy_message(r.message, sizeof r.message, "camera: VIDIOC_DQBUF failed\nEIO");
  r.total_ms = 12;
  return r;
}
inline std::string error_line(std::uint64_t cycle, std::uint16_t job) {
  return "cycle " + std::to_string(cycle) + " (plc job " + std::to_string(job) +
         " recipe 2): error 2: camera: VIDIOC_DQBUF failed\nEIO";
}

// Cycle `cycle`, job `job`: three candidates, the second (obj 4, score 0.625) picked.
inline CycleResult pick_result(std::uint64_t cycle, std::uint16_t job) {
  CycleResult r;
  r.request.cycle_id = cycle;
  r.request.job_id = job;
  r.request.recipe_id = 3;
  r.request.origin = CycleOrigin::Plc;
  r.candidate_count = 3;
  r.candidates[0].obj_id = 4;
  r.candidates[0].score = 0.5f;
  r.candidates[1].obj_id = 4;
  r.candidates[1].score = 0.625f;
  r.candidates[1].base = {512.5f, -20.0f, 130.3f, 180.0f, 0.0f, -35.5f};
  r.candidates[1].base_valid = true;
  r.candidates[2].obj_id = 4;
  r.candidates[2].score = 0.25f;
  r.chosen = 1;
  r.total_ms = 180.4;
  return r;
}
inline std::string pick_line(std::uint64_t cycle, std::uint16_t job) {
  return "cycle " + std::to_string(cycle) + " (plc job " + std::to_string(job) +
         " recipe 3): pick obj 4 at 512.5 -20.0 130.3 / 180.0 0.0 -35.5 score 0.625, 3 found, 180 ms";
}

// Cycle `cycle`, job `job`, from the control socket: nothing found.
inline CycleResult no_pick_result(std::uint64_t cycle, std::uint16_t job) {
  CycleResult r;
  r.request.cycle_id = cycle;
  r.request.job_id = job;
  r.request.recipe_id = 1;
  r.request.origin = CycleOrigin::Control;
  r.chosen = -1;
  r.candidate_count = 0;
  r.total_ms = 95.6;
  return r;
}
inline std::string no_pick_line(std::uint64_t cycle, std::uint16_t job) {
  return "cycle " + std::to_string(cycle) + " (control job " + std::to_string(job) +
         " recipe 1): no pick, 0 found, 96 ms";
}

}  // namespace mfcd::daemon::test
