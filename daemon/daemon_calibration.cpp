// mfcd-ctl calibrate: the control side of a calibration session. The session's computations run
// on CalibrationService's worker; captures go through the cell like a cycle, with picking paused.
#include "daemon/daemon_impl.hpp"
#include "daemon/log.hpp"

namespace mfcd::daemon {

using nlohmann::json;

void Daemon::handle_calibrate(ControlServer::ClientId client, const json& req) {
  std::string action;
  const auto refuse = [&](const std::string& why) {
    control_.reply(
        client, {{"ok", false}, {"error", "calibrate" + (action.empty() ? std::string() : " " + action) + ": " + why}});
  };
  try {
    action = req.contains("action") && req["action"].is_string() ? req["action"].get<std::string>() : "";
    if (action == "status") {
      json j = {{"ok", true}, {"session", calib_->state()}, {"picking", calibrating() ? "paused" : "running"}};
      if (calib_->busy()) j["working"] = calib_->working();
      if (capture_) j["capturing"] = true;
      j["camera_file"] = config_.camera.model.string();
      control_.reply(client, j);
      return;
    }
    if (action == "abort") {  // also while a job runs: it is queued behind it
      if (capture_) return refuse("a capture is in flight; abort again when it has answered");
      calib_->abort(client);
      update_ready();
      return;
    }
    if (calib_->busy())
      return refuse("busy: still working on '" + calib_->working() + "'; try again when it has answered");
    if (capture_) return refuse("busy: a capture is in flight");
    if (action == "start") {
      if (calib_->active())
        return refuse("a " + calib_->state().value("kind", "") +
                      " session is already running (mfcd-ctl calibrate abort ends it)");
      if (stopping_ || reload_pending_ || !cell_ok_)
        return refuse("mfcd is not ready (stopping, reloading, or the cell failed)");
      if (in_flight_ || pending_plc_) return refuse("busy: a pick cycle is running; try again when it is done");
      const std::string kind = req.contains("kind") && req["kind"].is_string() ? req["kind"].get<std::string>() : "";
      if (kind != "intrinsics" && kind != "hand-eye") return refuse("kind must be intrinsics or hand-eye");
      auto mode = vision::calib::HandEyeMode::eye_to_hand;
      if (kind == "hand-eye" && req.contains("mode")) {
        if (!req["mode"].is_string()) return refuse("mode must be eye-in-hand or eye-to-hand");
        mode = vision::calib::parse_hand_eye_mode(req["mode"].get<std::string>());
      }
      last_plc_pose_seq_.reset();
      calib_->start(client,
                    kind == "intrinsics" ? CalibrationService::Kind::Intrinsics : CalibrationService::Kind::HandEye,
                    mode, config_.camera.model, config_.calibration);
      update_ready();  // READY drops for the session
      return;
    }
    if (action == "capture" || action == "check") {
      const bool check = action == "check";
      if (!calib_->active())
        return refuse("no calibration session (mfcd-ctl calibrate intrinsics start, or hand-eye start)");
      if (check && (!calib_->hand_eye() || !calib_->computed()))
        return refuse("check needs a computed hand-eye calibration (calibrate compute first)");
      if (in_flight_ || reload_pending_ || stopping_ || !cell_ok_ || !cell_)
        return refuse("busy: a cycle or reload is running, or the cell failed");
      const bool from_plc = req.value("pose_from_plc", false);
      if (from_plc && req.contains("pose")) return refuse("give --pose or --pose-from-plc, not both");
      std::optional<vision::calib::RobotPose> flange;
      json about = json::object();
      if (req.contains("pose")) {
        flange = pose_from_json(req["pose"], "--pose");
        about["pose_source"] = "command line";
      } else if (from_plc) {
        const motion::RobotPoseReading p = link_.robot_pose();
        if (p.writes == 0)
          return refuse(
              "--pose-from-plc: the PLC has not written the robot pose block (registers 36..49, "
              "docs/register-map.md)");
        if (p.valid == 0)
          return refuse("--pose-from-plc: ROBOT_POSE_VALID (register 48) is 0: the PLC marks the pose as not current");
        if (last_plc_pose_seq_ && *last_plc_pose_seq_ == p.sequence)
          return refuse("--pose-from-plc: ROBOT_POSE_SEQ (register 49) is still " + std::to_string(p.sequence) +
                        " as for the previous view: the PLC has not written a new pose");
        flange = vision::calib::RobotPose{p.x_mm, p.y_mm, p.z_mm, p.rx_deg, p.ry_deg, p.rz_deg};
        about["pose_source"] = "plc";
        about["pose_sequence"] = p.sequence;
      }
      if (flange)
        about["pose"] = {flange->x_mm, flange->y_mm, flange->z_mm, flange->rx_deg, flange->ry_deg, flange->rz_deg};
      if (calib_->hand_eye() && !flange)
        return refuse("a hand-eye view needs the robot flange pose: --pose x,y,z,rx,ry,rz or --pose-from-plc");
      // The simulated cell stages the plate; a real cell ignores this (the plate is really there).
      PlateRequest plate;
      if (req.contains("sim_plate_pose")) {
        const auto p = pose_from_json(req["sim_plate_pose"], "--sim-plate-pose");
        plate.kind = PlateRequest::Kind::Camera;
        plate.pose = {p.x_mm, p.y_mm, p.z_mm, p.rx_deg, p.ry_deg, p.rz_deg};
      } else if (calib_->hand_eye() && flange) {
        plate.kind = calib_->eye_in_hand() ? PlateRequest::Kind::EyeInHand : PlateRequest::Kind::EyeToHand;
        plate.pose = {flange->x_mm, flange->y_mm, flange->z_mm, flange->rx_deg, flange->ry_deg, flange->rz_deg};
      }
      CycleRequest r;
      r.kind = CycleRequest::Kind::CalibrationCapture;
      r.origin = CycleOrigin::Control;
      r.cycle_id = next_cycle_++;
      r.trigger = Clock::now();
      r.deadline = r.trigger + std::chrono::milliseconds(config_.cycle_budget_ms);
      r.plate = plate;
      if (!submit(r)) return refuse("busy: the acquisition queue is full");
      in_flight_ = r;
      capture_ = PendingCapture{client, r.cycle_id, check, flange, std::move(about)};
      update_ready();
      return;
    }
    if (action == "compute") {
      if (!calib_->active()) return refuse("no calibration session");
      calib_->compute(client);
      return;
    }
    if (action == "apply") {
      if (!calib_->active()) return refuse("no calibration session");
      if (!calib_->computed()) return refuse("nothing computed yet (calibrate compute, then apply)");
      if (!req.value("confirm", false))
        return refuse("this writes " + config_.camera.model.string() +
                      ": confirm with --yes (mfcd-ctl asks y/N on a terminal)");
      calib_->apply(client, config_.recipes);
      return;
    }
    if (action == "rollback") {
      if (calib_->active()) return refuse("a calibration session is running: apply or abort it first");
      if (!req.value("confirm", false))
        return refuse("this overwrites " + config_.camera.model.string() +
                      " with its .previous copy: confirm with --yes");
      calib_->rollback(client, config_.camera.model);
      return;
    }
    refuse("unknown action '" + action + "' (start, capture, compute, check, apply, rollback, abort, status)");
  } catch (const std::exception& e) {  // bad field types, bad poses, unknown hand-eye mode
    refuse(e.what());
  }
}

void Daemon::on_calibration_image(const CycleResult& r) {
  in_flight_.reset();
  if (!capture_ || capture_->cycle != r.request.cycle_id) {
    logf(LogLevel::Warning, "calibration image of cycle %llu arrived with no capture waiting for it",
         static_cast<unsigned long long>(r.request.cycle_id));
    update_ready();
    return;
  }
  PendingCapture pc = std::move(*capture_);
  capture_.reset();
  if (!r.leds_off)
    logf(LogLevel::Error, "calibration capture %llu: LEDs were not all off after the capture",
         static_cast<unsigned long long>(r.request.cycle_id));
  if (r.error != CycleError::None) {
    json j = pc.about;
    j["ok"] = false;
    j["error"] = std::string("capture failed: ") + r.message;
    control_.reply(pc.client, j);
    update_ready();
    return;
  }
  if (pc.about.contains("pose_sequence")) last_plc_pose_seq_ = pc.about["pose_sequence"].get<std::uint16_t>();
  pc.about["capture_ms"] = r.capture_ms;
  cv::Mat1b image = cell_->calibration_image().clone();  // the cell's buffer is reused by the next capture
  if (pc.check)
    calib_->check(pc.client, std::move(image), *pc.flange, std::move(pc.about));
  else
    calib_->add_view(pc.client, std::move(image), pc.flange, std::move(pc.about));
  update_ready();
}

void Daemon::on_calibration_done() {
  for (auto& d : calib_->take_done()) {
    if (d.reload) {
      // The camera file changed: the cell is rebuilt on it through the ordinary reload path;
      // the client is answered when that is done.
      reload_waiters_.emplace_back(d.client, d.reply);
      logf(LogLevel::Info, "calibration: reloading so the cell uses the new camera file");
      reload_pending_ = true;
    } else {
      control_.reply(d.client, d.reply);
    }
  }
  update_ready();
  notify_status();
}

}  // namespace mfcd::daemon
