#include "daemon/cell.hpp"

#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

#include "daemon/log.hpp"
#include "daemon/snapshot.hpp"
#include "mfcd/hal/error.hpp"
#include "motion/pick_choice.hpp"
#include "motion/pick_transform.hpp"
#include "vision/camera/camera.hpp"

namespace mfcd::daemon {

namespace {

UniqueFd make_event_fd() {
  UniqueFd fd(::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK));
  if (!fd) throw std::system_error(errno, std::generic_category(), "eventfd");
  return fd;
}
void signal_fd(int fd) noexcept {
  const std::uint64_t one = 1;
  [[maybe_unused]] ssize_t n = ::write(fd, &one, sizeof one);
}
void drain_fd(int fd) noexcept {
  std::uint64_t v;
  [[maybe_unused]] ssize_t n = ::read(fd, &v, sizeof v);
}
// Waits for a wake-up or `ms`; returns true if woken.
bool wait_fd(int fd, int ms) noexcept {
  pollfd p{fd, POLLIN, 0};
  const int r = ::poll(&p, 1, ms);
  if (r > 0) {
    drain_fd(fd);
    return true;
  }
  return false;
}

}  // namespace

Cell::Cell(DaemonConfig config, VisionStageFactory vision, FrameSourceFactory source)
    : config_(std::move(config)), vision_factory_(std::move(vision)), source_factory_(std::move(source)) {
  acq_wake_ = make_event_fd();
  vision_wake_ = make_event_fd();
  result_fd_ = make_event_fd();
}

Cell::~Cell() {
  stop();  // the threads are gone before the members close their descriptors
}

void Cell::start() {
  stop_ = false;
  std::promise<void> acq_ready, vision_ready;
  auto acq_future = acq_ready.get_future(), vision_future = vision_ready.get_future();
  acquisition_ = std::thread([this, &acq_ready] { acquisition_main(acq_ready); });
  vision_ = std::thread([this, &vision_ready] { vision_main(vision_ready); });
  std::string error;
  try {
    acq_future.get();
  } catch (const std::exception& e) {
    error = std::string("camera: ") + e.what();
  }
  try {
    vision_future.get();
  } catch (const std::exception& e) {
    if (error.empty()) error = std::string("vision: ") + e.what();
  }
  if (!error.empty()) {
    stop();
    throw std::runtime_error(error);
  }
}

void Cell::stop() noexcept {
  stop_ = true;
  signal_fd(acq_wake_.get());
  signal_fd(vision_wake_.get());
  if (acquisition_.joinable()) acquisition_.join();
  if (vision_.joinable()) vision_.join();
}

bool Cell::submit(const CycleRequest& request) noexcept {
  if (!requests_.push(request)) return false;
  signal_fd(acq_wake_.get());
  return true;
}

CycleResult* Cell::begin_result() noexcept {
  drain_fd(result_fd_.get());  // before looking, so a result queued after this is never without a wake-up
  return results_.begin_read();
}

void Cell::acquisition_main(std::promise<void>& ready) {
  try {
    source_ = source_factory_(config_);
    source_->activate();
    const hal::ImageFormat format = source_->format();
    for (auto& slot : frames_.slots()) slot.allocate(format);
    start_gripper_camera();
    retained_.allocate(format);
    web_frames_.allocate(cv::Size(format.width, format.height));
    // Real lenses distort; the simulated cell renders the ideal pinhole the templates were taught
    // for (its camera file has zero distortion, and a fitted k1, k2 on its renders is noise).
    undistorter_ = source_->simulation()
                       ? vision::FrameUndistorter()
                       : vision::FrameUndistorter(vision::load_camera_config(config_.camera.model).camera);
    if (undistorter_.active()) {
      if (undistorter_.image_size() != cv::Size(format.width, format.height))
        throw std::runtime_error(config_.camera.model.string() +
                                 ": the camera file's image size differs from the camera's " +
                                 std::to_string(format.width) + "x" + std::to_string(format.height));
      logf(LogLevel::Info, "acquisition: undistorting every image with %s's lens distortion (K kept)",
           config_.camera.model.string().c_str());
    }
    calibration_image_.create(format.height, format.width);
    source_description_ = source_->describe();
    if (gripper_camera_) source_description_ += " + " + gripper_camera_->describe();
  } catch (...) {
    if (source_) source_->deactivate();
    gripper_camera_.reset();
    source_.reset();
    ready.set_exception(std::current_exception());
    return;
  }
  if (config_.realtime_priority > 0) {
    sched_param sp{};
    sp.sched_priority = config_.realtime_priority;
    const int err = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
    realtime_ = err == 0;
    if (err != 0)
      logf(LogLevel::Notice,
           "acquisition thread: SCHED_FIFO priority %d not permitted (%s); running SCHED_OTHER "
           "(grant LimitRTPRIO= or CAP_SYS_NICE)",
           config_.realtime_priority, std::strerror(err));
    else
      logf(LogLevel::Info, "acquisition thread: SCHED_FIFO priority %d", config_.realtime_priority);
  }
  pthread_setname_np(pthread_self(), "mfcd-acq");
  ready.set_value();

  while (!stop_.load()) {
    wait_fd(acq_wake_.get(), 200);
    acq_beat_.fetch_add(1, std::memory_order_relaxed);
    while (!stop_.load()) {
      const auto request = requests_.pop();
      if (!request) break;
      SimulatedWorld* sim = source_->simulation();
      const Eigen::Isometry3d* flange = request->flange_valid ? &request->base_T_flange : nullptr;
      if (request->kind == CycleRequest::Kind::RemovePicked) {
        if (sim) sim->remove_picked(request->picked_R_cam, request->picked_t_cam_mm, flange);  // may allocate
        continue;
      }
      if (request->kind == CycleRequest::Kind::Refill) {
        if (sim) sim->refill();
        continue;
      }
      FrameSlot* slot = frames_.begin_write();
      if (!slot) {  // cannot happen while the main thread keeps at most one cycle in flight
        frames_dropped_.fetch_add(1, std::memory_order_relaxed);
        continue;
      }
      slot->request = *request;
      slot->error[0] = '\0';
      const Clock::time_point t0 = Clock::now();
      const bool calibration = request->kind == CycleRequest::Kind::CalibrationCapture;
      try {
        // A calibration capture (operator-driven, picking paused) may re-stage the simulated
        // scene; that allocates, which the cycle path never does.
        // A real cell ignores the plate request: the plate is really there.
        if (calibration && sim) sim->show_plate(request->plate);
        if (request->kind == CycleRequest::Kind::GripCheck) {
          capture_gripper(*slot);
        } else {
          // Eye-in-hand: the simulated camera is where the job's robot pose holds it.
          if (!calibration && sim) sim->move_camera(flange);
          const hal::FrameSet& set = source_->capture();
          // Calibration images stay as the lens made them: intrinsics calibration fits the
          // distortion from them, hand-eye undistorts the board corners itself.
          if (calibration)
            copy_frame_set(set, slot->frames);
          else
            copy_frame_set(set, slot->frames, undistorter_);
        }
        slot->ok = true;
      } catch (const std::exception& e) {
        slot->ok = false;
        copy_message(slot->error, sizeof slot->error, e.what());
      }
      if (calibration) {
        try {
          if (sim) sim->show_plate({});
        } catch (const std::exception& e) {
          logf(LogLevel::Error, "simulated cell: putting the bin back after a calibration capture: %s", e.what());
        }
      }
      slot->captured = Clock::now();
      slot->capture_ms = ms_between(t0, slot->captured);
      slot->leds_after = source_->leds();
      slot->truth.count = 0;
      if (sim) sim->truth(slot->truth);
      frames_.end_write();
      signal_fd(vision_wake_.get());
    }
  }
  source_->deactivate();  // LEDs off, streaming stopped
  logf(LogLevel::Info, "acquisition stopped, LEDs off");
  gripper_camera_.reset();  // before the source: the simulated one renders with its world
  source_.reset();
}

void Cell::vision_main(std::promise<void>& ready) {
  try {
    stage_ = vision_factory_(config_);
    vision_description_ = stage_->describe();
    parts_ = stage_->parts();
    pipeline_result_.candidates.reserve(64);
    first_look_.candidates.reserve(64);
    snapshots_ = std::make_unique<SnapshotWriter>(config_);
    if (!snapshots_->not_replayable().empty())
      logf(LogLevel::Info, "snapshots will not be replayable by mfc-detect: %s", snapshots_->not_replayable().c_str());
  } catch (...) {
    stage_.reset();
    ready.set_exception(std::current_exception());
    return;
  }
  pthread_setname_np(pthread_self(), "mfcd-vision");
  ready.set_value();

  while (!stop_.load()) {
    wait_fd(vision_wake_.get(), 200);
    vision_beat_.fetch_add(1, std::memory_order_relaxed);
    while (FrameSlot* slot = frames_.begin_read()) {
      CycleResult* out = results_.begin_write();
      if (!out) {  // main thread not consuming: wait rather than drop a cycle's answer
        if (stop_.load()) return;
        wait_fd(vision_wake_.get(), 10);
        continue;
      }
      if (slot->request.kind == CycleRequest::Kind::CalibrationCapture ||
          slot->request.kind == CycleRequest::Kind::GripCheck) {
        if (slot->request.kind == CycleRequest::Kind::GripCheck)
          check_grip(*slot, *out);
        else
          hand_over_calibration_image(*slot, *out);
        results_.end_write();
        signal_fd(result_fd_.get());
        frames_.end_read();
        continue;
      }
      run_cycle(*slot, *out);
      const bool failed = out->error != CycleError::None || out->candidate_count == 0;
      const char* why = slot->request.snapshot ? "requested"
                        : config_.snapshots.on_failure && failed && slot->request.origin != CycleOrigin::Benchmark
                            ? (out->error != CycleError::None ? "failed cycle" : "nothing found")
                            : nullptr;
      retained_.keep_result(*out);  // before the result leaves: the slot is the main thread's then
      results_.end_write();
      signal_fd(result_fd_.get());
      // Kept after the result has left: a pick reported failed later is saved from here.
      retained_.keep_frames(*slot, retained_.result().error == CycleError::None ? stage_->last_edges() : nullptr);
      if (config_.web.enabled && slot->ok) web_frames_.publish(retained_.slot(), retained_.result(), retained_.edges());
      frames_.end_read();
      if (why) write_snapshot(why);
    }
    serve_snapshot_requests();
  }
  stage_.reset();
}

// What every result of a captured slot starts with. False when the capture failed: the result
// then carries the capture error and nothing else is to be done with the slot.
bool Cell::start_result(const FrameSlot& slot, CycleResult::Kind kind, CycleResult& out) {
  out = CycleResult{};
  out.kind = kind;
  out.request = slot.request;
  out.capture_ms = slot.capture_ms;
  out.leds_off = slot.leds_after == 0;
  if (slot.ok) return true;
  out.error = CycleError::Capture;
  copy_message(out.message, sizeof out.message, slot.error);
  return false;
}

void Cell::hand_over_calibration_image(const FrameSlot& slot, CycleResult& out) {
  if (start_result(slot, CycleResult::Kind::CalibrationImage, out))
    slot.mfc.ambient.copyTo(calibration_image_);  // same size: no allocation
  out.total_ms = ms_between(slot.request.trigger, Clock::now());
}

void Cell::run_cycle(FrameSlot& slot, CycleResult& out) {
  const Clock::time_point start = Clock::now();
  const bool captured = start_result(slot, CycleResult::Kind::Cycle, out);
  out.queue_ms = ms_between(slot.captured, start);
  out.truth = slot.truth;
  if (captured) {
    try {
      const CycleRequest& request = slot.request;
      const VisionInput in{slot.mfc, request.obj_id, request.deadline, &slot.truth};
      if (request.second_look) {
        fuse_look(in, request);
      } else {
        first_look_cycle_ = 0;  // the backend's state of the kept first look is overwritten now
        stage_->process(in, pipeline_result_);
      }
      const Clock::time_point vision_done = Clock::now();
      out.vision_ms = ms_between(start, vision_done);
      const auto& t = pipeline_result_.times;
      out.edges_ms = t.edges_ms, out.lines_ms = t.lines_ms, out.distance_ms = t.distance_ms;
      out.search_ms = t.search_ms, out.pose_ms = t.pose_ms, out.refine_ms = t.refine_ms;
      out.degraded = pipeline_result_.degraded;
      out.edge_pixels = pipeline_result_.edge_pixels;
      out.search_rounds = pipeline_result_.rounds;
      out.escalated = pipeline_result_.escalated;
      // A fused result is in the first look's camera frame: its picks go with that flange pose.
      const Eigen::Isometry3d* flange = !request.flange_valid ? nullptr
                                        : request.second_look ? &request.first_base_T_flange
                                                              : &request.base_T_flange;
      std::array<motion::PickCandidate, CycleResult::kMaxCandidates> choice{};
      const int n = fill_candidates(flange, choice, out);
      if (request.mode == 0)
        rank_picks(std::span<const motion::PickCandidate>(choice.data(), static_cast<std::size_t>(n)), out);
      if (!request.second_look) plan_look(request, out);
      out.choice_ms = ms_between(vision_done, Clock::now());
    } catch (const std::exception& e) {
      out.error = CycleError::Vision;
      copy_message(out.message, sizeof out.message, e.what());
    }
  }
  out.total_ms = ms_between(slot.request.trigger, Clock::now());
}

int Cell::fill_candidates(const Eigen::Isometry3d* base_T_flange,
                          std::array<motion::PickCandidate, CycleResult::kMaxCandidates>& choice,
                          CycleResult& out) const {
  // Pick choice and robot-base transform, on fixed-size arrays.
  const motion::PickTransform transform(config_.hand_eye);
  const int n =
      static_cast<int>(std::min<std::size_t>(pipeline_result_.candidates.size(), CycleResult::kMaxCandidates));
  out.candidate_count = n;
  for (int i = 0; i < n; ++i) {
    const vision::PoseCandidate& pc = pipeline_result_.candidates[static_cast<std::size_t>(i)];
    CandidateOut& c = out.candidates[static_cast<std::size_t>(i)];
    c.obj_id = pc.obj_id;
    c.score = static_cast<float>(pc.score);
    c.cost_px = static_cast<float>(pc.cost_px);
    c.refined = pc.refined;
    c.R_cam = pc.R_m2c;
    c.t_cam_mm = pc.t_m2c_mm;
    Eigen::Isometry3d cam_T_part = Eigen::Isometry3d::Identity();
    for (int r = 0; r < 3; ++r) {
      for (int k = 0; k < 3; ++k) cam_T_part.linear()(r, k) = pc.R_m2c(r, k);
      cam_T_part.translation()(r) = pc.t_m2c_mm[r];
    }
    const auto pose = transform.pick_pose(cam_T_part, base_T_flange ? std::optional(*base_T_flange) : std::nullopt);
    c.base_valid = pose.has_value();
    if (pose) c.base = *pose;
    // Grasp visibility: the pipeline's estimate for the recipes' grasp features (1 without any).
    c.grasp_visibility = static_cast<float>(pc.grasp_visibility);
    c.ambiguous = pc.ambiguous;
    c.box = pc.box;
    choice[static_cast<std::size_t>(i)] = {c.score,
                                           static_cast<float>(config_.pick.bin_floor_distance_mm - pc.t_m2c_mm[2]),
                                           c.grasp_visibility, c.ambiguous};
    const auto u = motion::pick_utility(choice[static_cast<std::size_t>(i)], config_.pick.choice);
    c.utility = u ? *u : -1.0f;
  }
  return n;
}

void Cell::rank_picks(std::span<const motion::PickCandidate> choice, CycleResult& out) const {
  std::array<std::uint16_t, CycleResult::kMaxCandidates> order{};
  const std::size_t m = motion::rank_picks(choice, config_.pick.choice, order);
  if (m == 0) return;
  if (!out.candidates[order[0]].base_valid) {
    out.error = CycleError::Transform;
    copy_message(out.message, sizeof out.message, "the chosen pick has no valid robot-base pose");
    return;
  }
  out.chosen = order[0];
  // Fall-backs the robot cannot be sent to are left out.
  for (std::size_t k = 0; k < m; ++k)
    if (out.candidates[order[k]].base_valid) out.ranked[static_cast<std::size_t>(out.ranked_count++)] = order[k];
}

bool Cell::request_snapshot(std::uint64_t cycle, const char* reason) noexcept {
  SnapshotRequest* r = snapshot_requests_.begin_write();
  if (!r) return false;
  r->cycle = cycle;
  copy_message(r->reason, sizeof r->reason, reason);
  snapshot_requests_.end_write();
  signal_fd(vision_wake_.get());
  return true;
}

void Cell::serve_snapshot_requests() {
  while (SnapshotRequest* r = snapshot_requests_.begin_read()) {
    const SnapshotRequest request = *r;
    snapshot_requests_.end_read();
    if (retained_.holds(request.cycle)) {
      write_snapshot(request.reason);
      continue;
    }
    CycleResult gone;
    gone.kind = CycleResult::Kind::SnapshotSaved;
    gone.request.cycle_id = request.cycle;
    const std::string why = "the frame set of cycle " + std::to_string(request.cycle) + " is no longer kept (cycle " +
                            std::to_string(retained_.cycle()) + " ran after it)";
    copy_message(gone.message, sizeof gone.message, why.c_str());
    post_result(gone);
  }
}

void Cell::write_snapshot(const char* reason) {
  CycleResult saved = retained_.result();
  saved.kind = CycleResult::Kind::SnapshotSaved;
  try {
    const std::string dir = snapshots_->save(retained_, stage_.get(), reason);
    copy_message(saved.snapshot_dir, sizeof saved.snapshot_dir, dir.c_str());
    saved.message[0] = '\0';
  } catch (const std::exception& e) {
    saved.snapshot_dir[0] = '\0';
    copy_message(saved.message, sizeof saved.message, e.what());
  }
  post_result(saved);
}

void Cell::post_result(const CycleResult& result) {
  CycleResult* out = nullptr;
  while (!(out = results_.begin_write()) && !stop_.load()) wait_fd(vision_wake_.get(), 10);
  if (!out) return;
  *out = result;
  results_.end_write();
  signal_fd(result_fd_.get());
}

}  // namespace mfcd::daemon
