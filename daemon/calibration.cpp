#include "daemon/calibration.hpp"

#include <pthread.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <system_error>

#include "daemon/log.hpp"
#include "vision/calib/store.hpp"
#include "vision/camera/camera.hpp"
#include "vision/templates/template_database.hpp"

namespace mfcd::daemon {

using nlohmann::json;
namespace calib = vision::calib;

namespace {

json pose_json(const cv::Matx44d& T) {
  const calib::RobotPose p = calib::RobotPose::from_matrix(T);
  return {{"x_mm", p.x_mm},     {"y_mm", p.y_mm},     {"z_mm", p.z_mm},
          {"rx_deg", p.rx_deg}, {"ry_deg", p.ry_deg}, {"rz_deg", p.rz_deg}};
}

json intrinsics_json(const calib::IntrinsicsResult& r) {
  json views = json::array();
  for (const auto& v : r.views) views.push_back({{"label", v.label}, {"rms_px", v.rms_px}, {"rejected", v.rejected}});
  json dist = json::array();
  for (double d : r.camera.distortion) dist.push_back(d);
  return {{"fx", r.camera.fx()},
          {"fy", r.camera.fy()},
          {"cx", r.camera.cx()},
          {"cy", r.camera.cy()},
          {"distortion", dist},
          {"rms_px", r.rms_px},
          {"used_views", r.used_views},
          {"views", views},
          {"std_dev_px", {r.std_dev[0], r.std_dev[1], r.std_dev[2], r.std_dev[3]}}};
}

json hand_eye_json(const calib::HandEyeResult& r) {
  json views = json::array();
  for (const auto& v : r.views)
    views.push_back(
        {{"label", v.label}, {"rms_px", v.rms_px}, {"position_mm", v.position_mm}, {"rotation_deg", v.rotation_deg}});
  const bool in_hand = r.mode == calib::HandEyeMode::eye_in_hand;
  return {{"mode", calib::to_string(r.mode)},
          {in_hand ? "flange_T_camera" : "base_T_camera", pose_json(r.hand_eye)},
          {in_hand ? "base_T_board" : "flange_T_board", pose_json(r.board)},
          {"initial_method", r.initial_method},
          {"initial_rms_px", r.initial_rms_px},
          {"rms_px", r.rms_px},
          {"position_rms_mm", r.position_rms_mm},
          {"rotation_rms_deg", r.rotation_rms_deg},
          {"axis_spread_deg", r.axis_spread_deg},
          {"views", views}};
}

json fail(const std::string& error) { return {{"ok", false}, {"error", error}}; }

}  // namespace

calib::RobotPose pose_from_json(const json& j, const std::string& what) {
  if (!j.is_array() || j.size() != 6)
    throw std::invalid_argument(what + ": expected six numbers x,y,z,rx,ry,rz (mm, degrees)");
  double v[6];
  for (std::size_t i = 0; i < 6; ++i) {
    if (!j[i].is_number() || !std::isfinite(j[i].get<double>()))
      throw std::invalid_argument(what + ": element " + std::to_string(i + 1) + " is not a finite number");
    v[i] = j[i].get<double>();
  }
  return {v[0], v[1], v[2], v[3], v[4], v[5]};
}

json invalidated_recipes(const fs::path& camera_file, const std::vector<RecipeConfig>& recipes) {
  json out = json::array();
  const vision::CameraConfig camera = vision::load_camera_config(camera_file);
  for (const auto& r : recipes) {
    if (!r.templates) continue;
    try {
      const vision::TemplateDatabase db = vision::load_template_database(*r.templates);
      vision::check_template_camera(db, camera, r.templates->string());
    } catch (const std::exception& e) {
      out.push_back({{"recipe", r.id}, {"part", r.part}, {"templates", r.templates->string()}, {"why", e.what()}});
    }
  }
  return out;
}

CalibrationService::CalibrationService() {
  done_fd_.reset(::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK));
  if (!done_fd_) throw std::system_error(errno, std::generic_category(), "eventfd");
  worker_ = std::thread([this] { worker_main(); });
}

CalibrationService::~CalibrationService() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  if (worker_.joinable()) worker_.join();
}

void CalibrationService::worker_main() {
  pthread_setname_np(pthread_self(), "mfcd-calib");
  for (;;) {
    std::function<void()> job;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [this] { return stop_ || !jobs_.empty(); });
      if (stop_) return;
      job = std::move(jobs_.front());
      jobs_.pop_front();
    }
    job();
  }
}

void CalibrationService::post(ClientId client, std::string what, std::function<Done()> job) {
  ++pending_;
  working_ = std::move(what);
  {
    std::lock_guard lock(mutex_);
    jobs_.push_back([this, client, job = std::move(job)] {
      Done d;
      try {
        d = job();
      } catch (const std::exception& e) {  // CalibrationError, file errors: the session stays as it was
        d.reply = fail(e.what());
      }
      d.client = client;
      json state = session_state();
      {
        std::lock_guard done_lock(mutex_);
        done_.emplace_back(std::move(d), std::move(state));
      }
      const std::uint64_t one = 1;
      [[maybe_unused]] ssize_t n = ::write(done_fd_.get(), &one, sizeof one);
    });
  }
  wake_.notify_one();
}

std::vector<CalibrationService::Done> CalibrationService::take_done() {
  std::uint64_t v;
  [[maybe_unused]] ssize_t n = ::read(done_fd_.get(), &v, sizeof v);
  std::vector<std::pair<Done, json>> done;
  {
    std::lock_guard lock(mutex_);
    done.swap(done_);
  }
  std::vector<Done> out;
  for (auto& [d, state] : done) {
    state_ = std::move(state);
    out.push_back(std::move(d));
    --pending_;
  }
  if (pending_ == 0) working_.clear();
  return out;
}

json CalibrationService::session_state() const {
  if (!session_) return {{"active", false}};
  return {{"active", true},
          {"kind", session_->kind() == calib::CalibrationSession::Kind::intrinsics ? "intrinsics" : "hand-eye"},
          {"mode", mode_},
          {"file", file_.string()},
          {"views", session_->view_count()},
          {"captures", captures_},
          {"computed", session_->has_pending()},
          {"figures", session_->has_pending() ? figures_ : ""}};
}

void CalibrationService::start(ClientId client, Kind kind, calib::HandEyeMode mode, const fs::path& camera_file,
                               const CalibrationSettings& settings) {
  post(client, "start", [=, this] {
    const calib::CheckerBoard board{settings.board_columns, settings.board_rows, settings.square_mm};
    std::unique_ptr<calib::CalibrationSession> s;
    if (kind == Kind::Intrinsics) {
      calib::IntrinsicsOptions options;
      options.distortion = calib::parse_distortion_model(settings.distortion);
      s = std::make_unique<calib::CalibrationSession>(
          calib::CalibrationSession::intrinsics(camera_file, board, options));
    } else {
      s = std::make_unique<calib::CalibrationSession>(calib::CalibrationSession::hand_eye(camera_file, mode, board));
    }
    session_ = std::move(s);
    file_ = camera_file;
    mode_ = kind == Kind::HandEye ? (mode == calib::HandEyeMode::eye_in_hand ? "eye-in-hand" : "eye-to-hand") : "";
    figures_.clear();
    captures_ = 0;
    logf(LogLevel::Notice, "calibration: %s session started on %s (%s)",
         kind == Kind::Intrinsics ? "intrinsics" : "hand-eye", camera_file.c_str(), board.describe().c_str());
    Done d;
    d.reply = {{"ok", true},
               {"board", board.describe()},
               {"file", camera_file.string()},
               {"message", "session started; picking is paused until it is applied or aborted"}};
    return d;
  });
}

void CalibrationService::add_view(ClientId client, cv::Mat1b image, std::optional<calib::RobotPose> flange,
                                  json about) {
  post(client, "capture", [this, image = std::move(image), flange, about = std::move(about)]() mutable {
    if (!session_) return Done{0, fail("calibrate capture: no calibration session (start one first)")};
    const std::string label = "view " + std::to_string(++captures_);
    const calib::ViewReport v = session_->add_view(image, flange, label);
    json j = std::move(about);
    j["ok"] = v.accepted;
    j["label"] = label;
    j["board_found"] = !v.corners.empty() || v.accepted;
    j["accepted"] = v.accepted;
    j["views"] = session_->view_count();
    if (!v.accepted) {
      j["reason"] = v.reason;
      j["error"] = label + " rejected: " + v.reason + " (" + std::to_string(session_->view_count()) + " views kept)";
    }
    logf(LogLevel::Info, "calibration: %s %s%s", label.c_str(),
         v.accepted ? "accepted" : "rejected: ", v.reason.c_str());
    return Done{0, j};
  });
}

void CalibrationService::compute(ClientId client) {
  post(client, "compute", [this] {
    if (!session_) return Done{0, fail("calibrate compute: no calibration session (start one first)")};
    figures_ = session_->compute();  // throws CalibrationError: nothing pending, nothing written
    json j = {{"ok", true}, {"figures", figures_}, {"file", file_.string()}};
    if (session_->intrinsics_result()) j["intrinsics"] = intrinsics_json(*session_->intrinsics_result());
    if (session_->hand_eye_result()) j["hand_eye"] = hand_eye_json(*session_->hand_eye_result());
    j["message"] = "not written yet: check the figures, then mfcd-ctl calibrate apply";
    logf(LogLevel::Notice, "calibration computed:\n%s", figures_.c_str());
    return Done{0, j};
  });
}

void CalibrationService::check(ClientId client, cv::Mat1b image, calib::RobotPose flange, json about) {
  post(client, "check", [this, image = std::move(image), flange, about = std::move(about)]() mutable {
    if (!session_) return Done{0, fail("calibrate check: no calibration session (start one first)")};
    const calib::HandEyeCheck c = session_->check(image, flange);
    json j = std::move(about);
    j["ok"] = c.board_found;
    j["board_found"] = c.board_found;
    if (!c.board_found) {
      j["error"] = "check: " + c.reason;
      return Done{0, j};
    }
    j["figures"] = c.summary();
    j["position_error_mm"] = c.position_error_mm;
    j["origin_error_mm"] = c.origin_error_mm;
    j["rotation_error_deg"] = c.rotation_error_deg;
    j["reprojection_rms_px"] = c.reprojection_rms_px;
    return Done{0, j};
  });
}

void CalibrationService::apply(ClientId client, std::vector<RecipeConfig> recipes) {
  post(client, "apply", [this, recipes = std::move(recipes)] {
    if (!session_) return Done{0, fail("calibrate apply: no calibration session")};
    session_->apply();  // throws: nothing computed, or the write failed (file unchanged)
    const calib::CalibrationStore store(file_);
    std::string message =
        "wrote " + file_.string() + " (previous kept as " + store.previous_file().string() + "); session closed";
    json invalidated = json::array();
    try {
      invalidated = invalidated_recipes(file_, recipes);
    } catch (const std::exception& e) {  // the file is written: say so, and why nothing was checked
      message += "; the recipes' templates could not be checked against it: " + std::string(e.what());
      logf(LogLevel::Warning, "calibration: checking the recipes' templates against %s: %s", file_.c_str(), e.what());
    }
    if (!invalidated.empty()) {
      message += "; the new camera invalidates the templates of";
      for (const auto& r : invalidated)
        message += " recipe " + std::to_string(r["recipe"].get<int>()) + " (" + r["part"].get<std::string>() + ")";
      message += ": re-teach them with mfc-teach --camera " + file_.string() +
                 " (docs/calibration.md), or calibrate rollback; the cell refuses them until then";
    }
    json j = {{"ok", true},
              {"file", file_.string()},
              {"previous", store.previous_file().string()},
              {"invalidated", invalidated},
              {"message", message}};
    logf(LogLevel::Notice, "calibration applied to %s (previous kept as %s)", file_.c_str(),
         store.previous_file().c_str());
    for (const auto& r : invalidated)
      logf(LogLevel::Warning, "calibration: recipe %d (%s): %s", r["recipe"].get<int>(),
           r["part"].get<std::string>().c_str(), r["why"].get<std::string>().c_str());
    session_.reset();
    return Done{0, j, true};
  });
}

void CalibrationService::abort(ClientId client) {
  post(client, "abort", [this] {
    const bool had = session_ != nullptr;
    session_.reset();
    if (had) logf(LogLevel::Notice, "calibration session aborted; nothing written");
    return Done{0, {{"ok", true}, {"message", had ? "session aborted; nothing written" : "no session was running"}}};
  });
}

void CalibrationService::rollback(ClientId client, const fs::path& camera_file) {
  post(client, "rollback", [camera_file] {
    calib::CalibrationSession::rollback(camera_file);  // throws when there is no previous file
    const calib::CalibrationStore store(camera_file);
    logf(LogLevel::Notice, "calibration rolled back: %s restored from %s", camera_file.c_str(),
         store.previous_file().c_str());
    return Done{0,
                {{"ok", true},
                 {"file", camera_file.string()},
                 {"message", "restored " + camera_file.string() + " from " + store.previous_file().string() +
                                 " (the replaced file is now the previous one: a second rollback undoes this)"}},
                true};
  });
}

}  // namespace mfcd::daemon
