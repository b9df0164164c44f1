// A stand-in for the daemon's cycle in robot-link tests: consumes PLC commands from a
// ModbusServer and publishes results through the same API the daemon uses.
#pragma once

#include "motion/modbus_server.hpp"
#include "motion/register_map.hpp"

#include <poll.h>

#include <atomic>
#include <chrono>
#include <thread>

namespace mfcd::motion::test {

using namespace std::chrono_literals;

// The pick the simulated daemon reports for a job: derived from the job id so a mix-up shows.
inline PickPose pick_for_job(std::uint16_t job) {
  return {100.0f + job, -250.5f, 42.25f, 180.0f, -0.5f, static_cast<float>(job % 360) - 90.0f};
}

// The job's ranked picks: rank 0 is pick_for_job; each fall-back is 1000 mm further along x,
// its candidate index one higher and its score 0.125 lower.
inline constexpr std::uint16_t kSimPicksPerJob = 3;
inline RankedPick ranked_pick(std::uint16_t job, std::uint16_t rank) {
  RankedPick p{pick_for_job(job), 0.875f - 0.125f * rank, static_cast<std::uint16_t>(2 + rank), 0};
  p.pick.x_mm += 1000.0f * rank;
  return p;
}

// Second look (map version 4): a TRIGGER or SAVE_SCENE with recipe kSimLookRecipe + k
// (k = 1..3) is answered with a second look wanted for reason k (reg::LookReason) from
// look_pose_for_job, and no pick; a LOOK is answered with the fused pick, pick_for_job.
inline constexpr std::uint16_t kSimLookRecipe = 90;
inline PickPose look_pose_for_job(std::uint16_t job) {
  return {300.0f + job, -120.25f, 615.5f, 179.5f, -12.75f, static_cast<float>(job % 180) - 45.0f};
}

// Gripper check (map version 5): a CHECK_GRIP is answered with a grip result for the job it
// checks and no pick: GripState PoseError for recipe kSimGripRecipe + 2, NotGrasped for
// kSimGripRecipe + 3, Expected for any other; the part's pose in the tool frame is
// grip_pose_for_job (0.0 when not grasped), the errors kSimGripErrors.
inline constexpr std::uint16_t kSimGripRecipe = 80;
inline PickPose grip_pose_for_job(std::uint16_t checked_job) {
  return {1.5f,  -0.75f, 148.0f + static_cast<float>(checked_job % 16),
          0.25f, -0.5f,  static_cast<float>(checked_job % 90)};
}
struct SimGripErrors {
  float translation_mm, rotation_deg;
};
inline SimGripErrors sim_grip_errors(reg::GripState state) {
  return state == reg::GripState::PoseError ? SimGripErrors{6.25f, 4.5f} : SimGripErrors{0.5f, 0.25f};
}
inline reg::GripState sim_grip_state(std::uint16_t recipe) {
  if (recipe == kSimGripRecipe + 2) return reg::GripState::PoseError;
  if (recipe == kSimGripRecipe + 3) return reg::GripState::NotGrasped;
  return reg::GripState::Expected;
}

// Stands in for the daemon's cycle: consumes PLC commands from the server and publishes
// results through the same API the daemon uses.
class SimulatedDaemon {
 public:
  explicit SimulatedDaemon(ModbusServer& server, std::chrono::milliseconds cycle = 30ms)
      : server_(server), cycle_(cycle) {
    report_.ready = 1;
    report_.vision_ok = 1;
    server_.publish(report_);
    thread_ = std::thread([this] { loop(); });
  }
  ~SimulatedDaemon() {
    stop_ = true;
    thread_.join();
  }
  std::atomic<int> triggers{0}, resets{0}, save_scenes{0}, nexts{0}, pick_results{0}, looks{0}, checks{0};
  // The last NEXT and PICK_RESULT as the daemon received them; `order` records the kinds as
  // they arrived, two bits each (1 = NEXT, 2 = PICK_RESULT, 3 = CHECK_GRIP), for checks of one
  // write carrying two.
  std::atomic<std::uint16_t> next_rank{0}, result_job{0}, result_rank{0xffff}, result_outcome{0};
  std::atomic<std::uint32_t> order{0};
  std::atomic<std::uint16_t> last_mode{0xffff}, last_recipe{0xffff};
  // The last LOOK as the daemon received it.
  std::atomic<std::uint16_t> look_job{0}, look_of_job{0};
  // The last CHECK_GRIP as the daemon received it.
  std::atomic<std::uint16_t> check_job{0}, check_of_job{0}, check_rank{0xffff};
  std::atomic<bool> fail_next{false};

 private:
  void loop() {
    while (!stop_) {
      pollfd p{server_.command_fd(), POLLIN, 0};
      ::poll(&p, 1, 20);
      while (auto cmd = server_.next_command()) {
        if (cmd->kind == PlcCommand::Kind::Reset) {
          report_.error_code = 0;
          server_.publish(report_);
          ++resets;
          continue;
        }
        if (cmd->kind == PlcCommand::Kind::Next) {
          // As the daemon does: the report follows the pick the server published.
          report_.pick_rank = cmd->rank;
          report_.pick = report_.ranked[cmd->rank].pick;
          server_.publish(report_);
          next_rank = cmd->rank;
          order = order * 4 + 1;
          ++nexts;
          continue;
        }
        if (cmd->kind == PlcCommand::Kind::PickResult) {
          result_job = cmd->job_id;
          result_rank = cmd->rank;
          result_outcome = cmd->outcome;
          order = order * 4 + 2;
          ++pick_results;
          continue;
        }
        const bool save = cmd->kind == PlcCommand::Kind::SaveScene;
        const bool look = cmd->kind == PlcCommand::Kind::Look;
        const bool check = cmd->kind == PlcCommand::Kind::CheckGrip;
        if (save)
          ++save_scenes;
        else if (look)
          ++looks;
        else if (check)
          ++checks;
        else
          ++triggers;
        if (look) {
          look_job = cmd->job_id;
          look_of_job = cmd->look_of_job;
        }
        if (check) {
          check_job = cmd->job_id;
          check_of_job = cmd->check_of_job;
          check_rank = cmd->rank;
          order = order * 4 + 3;
        }
        last_mode = cmd->mode;
        last_recipe = cmd->recipe_id;
        std::this_thread::sleep_for(cycle_);
        report_.job_id = cmd->job_id;
        report_.recipe_id = cmd->recipe_id;
        report_.cycle_time_ms = static_cast<std::uint16_t>(cycle_.count());
        report_.objects_remaining = 7;
        report_.candidate_index = 2;
        report_.candidate_count = 5;
        if (fail_next.exchange(false)) {
          report_.error_code = 301;
          report_.pick_valid = 0;
        } else {
          report_.pick_valid = cmd->mode == 0;
          report_.pick = pick_for_job(cmd->job_id);
          report_.score = 0.875f;
        }
        const auto reason = static_cast<std::uint16_t>(cmd->recipe_id - kSimLookRecipe);
        const bool wants_look = !look && !check && report_.error_code == 0 && reason >= 1 && reason <= 3;
        report_.look_wanted = wants_look;
        report_.look_reason = wants_look ? reason : 0;
        report_.look_pose = wants_look ? look_pose_for_job(cmd->job_id) : PickPose{};
        if (wants_look) report_.pick_valid = 0;
        // A check's result: the grip fields, no pick. Every other result: grip fields 0.
        const auto grip = check && report_.error_code == 0 ? sim_grip_state(cmd->recipe_id) : reg::GripState::None;
        const bool found = grip == reg::GripState::Expected || grip == reg::GripState::PoseError;
        report_.grip_state = static_cast<std::uint16_t>(grip);
        report_.grip_of_job = grip != reg::GripState::None ? cmd->check_of_job : 0;
        report_.grip_pose = found ? grip_pose_for_job(cmd->check_of_job) : PickPose{};
        report_.grip_translation_mm = found ? sim_grip_errors(grip).translation_mm : 0.0f;
        report_.grip_rotation_deg = found ? sim_grip_errors(grip).rotation_deg : 0.0f;
        if (check) report_.pick_valid = 0;
        report_.pick_rank = 0;
        report_.pick_count = report_.pick_valid ? kSimPicksPerJob : 0;
        for (std::uint16_t k = 0; k < report_.pick_count; ++k) report_.ranked[k] = ranked_pick(cmd->job_id, k);
        if (save) ++report_.snapshots_saved;
        server_.publish(report_);
      }
    }
  }

  ModbusServer& server_;
  std::chrono::milliseconds cycle_;
  RobotReport report_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace mfcd::motion::test
