// The daemon's cycle bookkeeping: starting cycles for the PLC, the control socket and continuous
// mode, publishing their results on the robot link, and answering every accepted job.
#include <algorithm>

#include "daemon/daemon_impl.hpp"
#include "daemon/journal_log.hpp"
#include "daemon/log.hpp"
#include "daemon/look_planner.hpp"
#include "daemon/report.hpp"
#include "motion/pick_transform.hpp"
#include "motion/register_map.hpp"

namespace mfcd::daemon {

using nlohmann::json;

void Daemon::publish() { link_.publish(report_); }

void Daemon::update_ready() {
  // A calibration session pauses picking: the camera looks at the calibration plate, not the bin.
  const std::uint16_t ready =
      cell_ok_ && !in_flight_ && !reload_pending_ && !stopping_ && !calibrating() && config_.mode == RunMode::Triggered;
  const std::uint16_t vision_ok = cell_ok_ && frames_ok_;
  if (ready != report_.ready || vision_ok != report_.vision_ok) {
    report_.ready = ready;
    report_.vision_ok = vision_ok;
    publish();
  }
}

std::optional<std::uint64_t> Daemon::start_cycle(CycleOrigin origin, std::uint16_t job, std::uint16_t recipe,
                                                 std::uint16_t mode, bool snapshot, const FirstLook* first) {
  if (!cell_ || in_flight_) return std::nullopt;
  CycleRequest r;
  r.origin = origin;
  r.cycle_id = next_cycle_++;
  r.job_id = job;
  r.recipe_id = recipe;
  r.mode = mode;
  r.snapshot = snapshot;
  r.trigger = Clock::now();
  // The pipeline gets the budget minus a reserve for pick choice and publishing.
  const auto budget = std::chrono::milliseconds(config_.cycle_budget_ms);
  r.deadline = r.trigger + budget - std::min<std::chrono::milliseconds>(std::chrono::milliseconds(50), budget / 10);
  // A job that cannot run is answered at once, as a cycle with its error.
  const auto fail_now = [&](CycleError error, const std::string& msg) {
    CycleResult fail;
    fail.request = r;
    fail.error = error;
    copy_message(fail.message, sizeof fail.message, msg.c_str());
    on_result(fail);
    return r.cycle_id;
  };
  const RecipeConfig* rc = config_.recipe(recipe);
  if (!rc)
    return fail_now(CycleError::UnknownRecipe,
                    "recipe " + std::to_string(recipe) + " is not in the configuration (" + config_.source + ")");
  r.obj_id = rc->obj_id;
  if (config_.hand_eye.setup == motion::HandEyeSetup::EyeInHand) {
    // The camera is where the robot holds it: the PLC's robot pose block, as it is now.
    const motion::RobotPoseReading p = link_.robot_pose();
    if (p.writes == 0 || p.valid != 1)
      return fail_now(CycleError::NoRobotPose,
                      p.writes == 0 ? "eye_in_hand: the PLC has not written the robot pose block (registers 36..49)"
                                    : "eye_in_hand: ROBOT_POSE_VALID (register 48) is 0: the pose is not current");
    r.flange_valid = true;
    r.base_T_flange = motion::pose_to_isometry({{p.x_mm, p.y_mm, p.z_mm}, {p.rx_deg, p.ry_deg, p.rz_deg}});
  }
  if (first) {
    r.second_look = true;
    r.first_cycle = first->cycle;
    r.first_base_T_flange = first->base_T_flange;
  }
  if (!submit(r)) return std::nullopt;
  in_flight_ = r;
  update_ready();
  return r.cycle_id;
}

void Daemon::on_plc_command(const motion::PlcCommand& cmd) {
  using Kind = motion::PlcCommand::Kind;
  switch (cmd.kind) {
    case Kind::Reset:
      logf(LogLevel::Info, "PLC: RESET (error code %u cleared)", report_.error_code);
      report_.error_code = 0;
      pending_plc_.reset();
      publish();
      return;
    case Kind::Next:
      on_next_pick(cmd);
      return;
    case Kind::PickResult:
      on_pick_result(cmd);
      return;
    case Kind::Trigger:
    case Kind::SaveScene:
    case Kind::Look:
    case Kind::CheckGrip:
      break;
  }
  logf(LogLevel::Debug, "PLC: %s job %u recipe %u mode %u",
       cmd.kind == Kind::SaveScene   ? "SAVE_SCENE"
       : cmd.kind == Kind::Look      ? "LOOK"
       : cmd.kind == Kind::CheckGrip ? "CHECK_GRIP"
                                     : "TRIGGER",
       cmd.job_id, cmd.recipe_id, cmd.mode);
  if (calibrating()) {
    // READY is clear during a session, so only a trigger racing the session's start gets here:
    // it is answered at once with ERROR_CODE 6 rather than left pending.
    logf(LogLevel::Warning, "PLC: TRIGGER job %u refused: a calibration session is running", cmd.job_id);
    report_.job_id = cmd.job_id;
    report_.recipe_id = cmd.recipe_id;
    report_.error_code = static_cast<std::uint16_t>(CycleError::Calibrating);
    report_.pick_valid = 0;
    clear_look();
    publish();
    return;
  }
  if (in_flight_ || reload_pending_) {
    pending_plc_ = cmd;  // accepted by the server during a local cycle: runs right after it
    return;
  }
  start_plc_job(cmd);
}

void Daemon::on_next_pick(const motion::PlcCommand& cmd) {
  // The Modbus server has published this pick already; the report follows it, so the CAN link
  // sends it and later reports keep it.
  if (cmd.job_id != report_.job_id || cmd.rank >= report_.pick_count) return;
  const motion::RankedPick& p = report_.ranked[cmd.rank];
  report_.pick_rank = cmd.rank;
  report_.pick = p.pick;
  report_.score = p.score;
  report_.candidate_index = p.candidate_index;
  stats_.add_next_pick();
  logf(LogLevel::Info, "PLC: NEXT: job %u, pick %u of %u (candidate %u, score %.2f)", cmd.job_id, cmd.rank + 1,
       report_.pick_count, p.candidate_index, p.score);
  if (!last_result_.is_null() && last_result_["cycle"] == last_job_cycle_) last_result_["pick_rank"] = cmd.rank;
  publish();
}

void Daemon::on_pick_result(const motion::PlcCommand& cmd) {
  static constexpr const char* kNames[] = {"none", "ok", "missed", "unreachable", "collision", "dropped"};
  const char* outcome = cmd.outcome < std::size(kNames) ? kNames[cmd.outcome] : "?";
  stats_.add_pick_result(cmd.outcome);
  const bool failed = cmd.outcome != static_cast<std::uint16_t>(motion::reg::PickOutcome::Ok);
  logf(failed ? LogLevel::Warning : LogLevel::Info, "PLC: pick result of job %u, pick %u: %s", cmd.job_id, cmd.rank + 1,
       outcome);
  const bool ours = cmd.job_id == report_.job_id && last_job_cycle_ != 0;
  if (ours && !last_result_.is_null() && last_result_["cycle"] == last_job_cycle_)
    last_result_["pick_results"].push_back({{"rank", cmd.rank}, {"outcome", outcome}});
  if (!failed || !config_.snapshots.on_failed_pick || !ours || !cell_) return;
  const std::string reason = std::string("pick result: ") + outcome + " (job " + std::to_string(cmd.job_id) +
                             ", pick " + std::to_string(cmd.rank + 1) + ")";
  if (!cell_->request_snapshot(last_job_cycle_, reason.c_str()))
    logf(LogLevel::Warning, "PLC: no snapshot of job %u: the snapshot queue is full", cmd.job_id);
}

void Daemon::start_plc_job(const motion::PlcCommand& cmd) {
  if (cmd.kind == motion::PlcCommand::Kind::CheckGrip) return start_grip_check(cmd);
  const bool snapshot = cmd.kind == motion::PlcCommand::Kind::SaveScene;
  const FirstLook* first = nullptr;
  if (cmd.kind == motion::PlcCommand::Kind::Look) {
    // The server took LOOK on a result that asked for it; a control-socket cycle since then has
    // replaced the first look's images in the vision backend.
    if (!first_look_ || first_look_->job != cmd.look_of_job)
      return answer_job(cmd.job_id, cmd.recipe_id, CycleError::Unavailable,
                        "LOOK: the first look it continues is no longer kept");
    first = &*first_look_;
  }
  if (!start_cycle(CycleOrigin::Plc, cmd.job_id, cmd.recipe_id, cmd.mode, snapshot, first))
    answer_job(cmd.job_id, cmd.recipe_id, CycleError::Unavailable,
               cell_ ? "the cell's request queue is full" : "no cell is running");
}

void Daemon::answer_job(std::uint16_t job, std::uint16_t recipe, CycleError error, const char* why) {
  logf(LogLevel::Error, "PLC: job %u (recipe %u) not run: %s; answered with error code %u", job, recipe, why,
       static_cast<unsigned>(error));
  report_.job_id = job;
  report_.recipe_id = recipe;
  report_.error_code = static_cast<std::uint16_t>(error);
  report_.pick_valid = 0;
  report_.candidate_count = 0;
  report_.candidate_index = 0;
  report_.objects_remaining = 0;
  report_.pick = motion::PickPose{};
  report_.score = 0.0f;
  clear_look();
  clear_grip();
  last_pick_ = {};
  publish();
}

void Daemon::clear_look() {
  report_.look_wanted = 0;
  report_.look_reason = 0;
  report_.look_pose = motion::PickPose{};
  first_look_.reset();
}

bool Daemon::submit(const CycleRequest& r) {
  if (!cell_ || !cell_->submit(r)) return false;
  const auto budget = std::chrono::milliseconds(config_.cycle_budget_ms);
  busy_until_ = std::max(busy_until_, r.kind == CycleRequest::Kind::Capture ? r.deadline : Clock::now() + budget);
  return true;
}

void Daemon::on_result(const CycleResult& r) {
  if (r.kind == CycleResult::Kind::CalibrationImage) {
    on_calibration_image(r);
    return;
  }
  if (r.kind == CycleResult::Kind::SnapshotSaved) {
    if (r.snapshot_dir[0]) {
      logf(LogLevel::Info, "snapshot of cycle %llu saved in %s", static_cast<unsigned long long>(r.request.cycle_id),
           r.snapshot_dir);
      ++report_.snapshots_saved;  // wraps, as SNAPSHOT_COUNT does
      publish();
    } else {
      logf(LogLevel::Warning, "snapshot of cycle %llu failed: %s", static_cast<unsigned long long>(r.request.cycle_id),
           r.message);
    }
    for (auto it = waiters_.begin(); it != waiters_.end();) {
      if (it->what == Waiter::What::Snapshot && it->cycle == r.request.cycle_id) {
        if (r.snapshot_dir[0])
          control_.reply(it->client, {{"ok", true}, {"snapshot", r.snapshot_dir}, {"result", result_json(r, config_)}});
        else
          control_.reply(it->client, {{"ok", false}, {"error", r.message}});
        it = waiters_.erase(it);
      } else {
        ++it;
      }
    }
    return;
  }
  if (in_flight_ && in_flight_->cycle_id == r.request.cycle_id) in_flight_.reset();
  if (r.request.kind == CycleRequest::Kind::GripCheck) return on_grip_result(r);
  if (r.error == CycleError::Capture || r.error == CycleError::Vision) {
    if (frames_ok_) logf(LogLevel::Error, "VISION_OK cleared: %s; the next cycle retries", r.message);
    frames_ok_ = false;
  } else if (r.error != CycleError::UnknownRecipe) {  // captured and processed: camera and vision work
    if (!frames_ok_)
      logf(LogLevel::Notice, "VISION_OK set again: cycle %llu captured and processed its frames",
           static_cast<unsigned long long>(r.request.cycle_id));
    frames_ok_ = true;
  }
  const bool overrun = stats_.add(r, config_.cycle_budget_ms);
  last_result_ = result_json(r, config_);
  const unsigned long long id = r.request.cycle_id;
  // The cycle line (journald: with MFCD_* fields). Main thread, after the vision worker handed the
  // result over; never on the frame path.
  log_cycle_result(r);
  if (overrun)
    logf(LogLevel::Warning, "cycle %llu overran its budget: %.0f ms > %d ms (capture %.0f, vision %.0f; %s)", id,
         r.total_ms, config_.cycle_budget_ms, r.capture_ms, r.vision_ms,
         r.degraded ? "degraded result" : "full result");
  if (!r.leds_off) logf(LogLevel::Error, "cycle %llu: LEDs were not all off after the capture", id);

  // Robot link: PLC jobs and continuous cycles are published; control-socket cycles are not (they
  // would change JOB_ID_ECHO under the PLC's handshake).
  if (r.request.origin == CycleOrigin::Plc || r.request.origin == CycleOrigin::Continuous) report_job(r);
  report_.ready = 0;  // recomputed below, in the same publish
  update_ready();
  publish();

  // The simulated robot takes the part it was given.
  if (r.chosen >= 0 && cell_) {
    CycleRequest take;
    take.kind = CycleRequest::Kind::RemovePicked;
    take.picked_t_cam_mm = r.candidates[static_cast<std::size_t>(r.chosen)].t_cam_mm;
    take.picked_R_cam = r.candidates[static_cast<std::size_t>(r.chosen)].R_cam;
    take.flange_valid = r.request.flange_valid;
    take.base_T_flange = r.request.second_look ? r.request.first_base_T_flange : r.request.base_T_flange;
    submit(take);
  } else if (r.error == CycleError::None && r.candidate_count == 0 && r.truth.count > 0 && cell_) {
    // Simulated cell: vision sees nothing in a bin that still holds parts (all unrecognised); like
    // an operator would, tip in a fresh bin so the cell does not stall on one scene.
    CycleRequest refill;
    refill.kind = CycleRequest::Kind::Refill;
    submit(refill);
  }
  for (auto it = waiters_.begin(); it != waiters_.end();) {
    if (it->what == Waiter::What::Trigger && it->cycle == r.request.cycle_id) {
      json j = {{"ok", r.error == CycleError::None}, {"result", last_result_}};
      if (r.error != CycleError::None) j["error"] = r.message;
      control_.reply(it->client, j);
      it = waiters_.erase(it);
    } else {
      ++it;
    }
  }
  notify_status();
}

void Daemon::report_job(const CycleResult& r) {
  report_.job_id = r.request.job_id;
  report_.recipe_id = r.request.recipe_id;
  report_.error_code = static_cast<std::uint16_t>(r.error);
  report_.objects_remaining = static_cast<std::uint16_t>(r.candidate_count);
  report_.cycle_time_ms = static_cast<std::uint16_t>(std::min(65535.0, r.total_ms));
  report_.candidate_count = static_cast<std::uint16_t>(r.candidate_count);
  report_.candidate_index = static_cast<std::uint16_t>(std::max(0, r.chosen));
  report_.pick_valid = r.chosen >= 0;
  report_.pick = r.chosen >= 0 ? r.candidates[static_cast<std::size_t>(r.chosen)].base : motion::PickPose{};
  report_.score = r.chosen >= 0 ? r.candidates[static_cast<std::size_t>(r.chosen)].score : 0.0f;
  // The job's picks in order, for NEXT (ranked[0] is the chosen one).
  report_.pick_rank = 0;
  report_.pick_count = 0;
  last_pick_ = {r.request.job_id, r.request.recipe_id, 0, {}};
  for (int k = 0; r.chosen >= 0 && k < r.ranked_count && report_.pick_count < motion::kMaxRankedPicks; ++k) {
    const std::uint16_t index = r.ranked[static_cast<std::size_t>(k)];
    const CandidateOut& c = r.candidates[index];
    last_pick_.obj_id[report_.pick_count] = c.obj_id;
    report_.ranked[report_.pick_count++] = {c.base, c.score, index, 0};
  }
  last_pick_.count = report_.pick_count;
  clear_grip();
  clear_look();
  if (r.look_wanted) {
    report_.look_wanted = 1;
    report_.look_reason = r.look_reason;
    report_.look_pose = r.look_pose;
    first_look_ = FirstLook{r.request.job_id, r.request.cycle_id, r.request.base_T_flange};
    logf(LogLevel::Info, "job %u asks for a second look (%s) from flange (%.1f, %.1f, %.1f) mm", r.request.job_id,
         to_string(static_cast<LookReason>(r.look_reason)), r.look_pose.x_mm, r.look_pose.y_mm, r.look_pose.z_mm);
  }
  last_job_cycle_ = r.request.cycle_id;
}

void Daemon::after_cycle() {
  if (in_flight_) return;
  if (stopping_) return;
  if (reload_pending_) {
    std::string message;
    const bool ok = reload(message);
    for (auto& [client, base] : reload_waiters_) {
      json j = base.is_object() ? base : json::object();
      if (ok) {
        j["ok"] = j.value("ok", true);
        j["reload"] = message;
      } else {
        j["ok"] = false;
        j["error"] = j.contains("message") ? j.value("message", "") + "; but " + message : message;
      }
      if (!base.is_object()) j["message"] = message;
      control_.reply(client, j);
    }
    reload_waiters_.clear();
    reload_pending_ = false;
    update_ready();
    notify_status();
  }
  if (pending_plc_) {
    const auto cmd = *pending_plc_;
    pending_plc_.reset();
    start_plc_job(cmd);
    return;
  }
  if (config_.mode == RunMode::Continuous && cell_ok_ && !calibrating()) {
    const std::uint16_t job = next_continuous_job_;
    next_continuous_job_ = static_cast<std::uint16_t>(next_continuous_job_ == 65535 ? 1 : next_continuous_job_ + 1);
    start_cycle(CycleOrigin::Continuous, job, static_cast<std::uint16_t>(selected_recipe_), 0, false);
  }
}

}  // namespace mfcd::daemon
