#pragma once
// The cell's frame path: an acquisition thread (HAL sequencer, SCHED_FIFO where permitted) and a
// vision worker, joined by a lock-free SPSC ring of preallocated FrameSlots; results go to the main
// thread through a second SPSC ring of CycleResults, with an eventfd to wake its poll loop.
//
//   main --requests(SpscRing)--> acquisition --FrameSlots(SpscRing)--> vision --CycleResults(SpscRing)--> main
//
// In steady state nothing on this path allocates, locks or does blocking I/O besides the device
// reads themselves and eventfd wake-ups; snapshots (explicitly requested, or of failed cycles) are
// written by the vision worker after the cycle's result has been handed over.
#include <atomic>
#include <functional>
#include <future>
#include <memory>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "base/unique_fd.hpp"
#include "daemon/config.hpp"
#include "daemon/cycle.hpp"
#include "daemon/frame_source.hpp"
#include "daemon/gripper_camera.hpp"
#include "daemon/latest_frame.hpp"
#include "daemon/retained_job.hpp"
#include "daemon/snapshot.hpp"
#include "daemon/vision_stage.hpp"
#include "motion/pick_choice.hpp"
#include "motion/spsc_ring.hpp"
#include "vision/camera/frame_undistorter.hpp"

namespace mfcd::daemon {

class Cell {
 public:
  static constexpr std::size_t kFrameSlots = 4;
  static constexpr std::size_t kResultSlots = 8;

  Cell(DaemonConfig config, VisionStageFactory vision, FrameSourceFactory source = make_frame_source);
  ~Cell();
  Cell(const Cell&) = delete;
  Cell& operator=(const Cell&) = delete;

  // Starts both threads; each builds its backend in its own thread. Returns once both are ready;
  // throws std::runtime_error with the first failure (threads already joined).
  void start();
  // Stops and joins the threads; the acquisition thread switches the LEDs off (deactivate) last.
  void stop() noexcept;

  // --- main thread ---
  bool submit(const CycleRequest& request) noexcept;  // false when the request queue is full
  int result_fd() const { return result_fd_.get(); }  // readable when results are queued
  CycleResult* begin_result() noexcept;               // drains the eventfd; nullptr when none
  void end_result() noexcept { results_.end_read(); }

  // Asks the vision worker to save the kept frame set of `cycle` (the last cycle it ran) as a
  // snapshot; the answer is a SnapshotSaved result, with an error when that cycle's frames are
  // no longer kept. False when the request queue is full.
  bool request_snapshot(std::uint64_t cycle, const char* reason) noexcept;

  // The ambient image of the last CalibrationCapture (see CycleResult::Kind::CalibrationImage);
  // preallocated, written by the vision thread before it posts that result.
  const cv::Mat1b& calibration_image() const { return calibration_image_; }
  // The last cycle's images and result for the web view (written by the vision worker when
  // web.enabled; one reader at a time). Lives as long as the cell.
  LatestFrame* web_frames() { return &web_frames_; }

  const DaemonConfig& config() const { return config_; }
  const std::string& source_description() const { return source_description_; }
  const std::string& vision_description() const { return vision_description_; }
  const std::vector<std::pair<int, std::string>>& parts() const { return parts_; }
  bool realtime() const { return realtime_; }
  // Incremented by each thread at every wake-up (at least every 200 ms when idle); the main thread
  // sends the systemd watchdog only while both keep moving.
  std::uint64_t acquisition_heartbeat() const { return acq_beat_.load(std::memory_order_relaxed); }
  std::uint64_t vision_heartbeat() const { return vision_beat_.load(std::memory_order_relaxed); }
  std::uint64_t frames_dropped() const { return frames_dropped_.load(std::memory_order_relaxed); }

 private:
  void acquisition_main(std::promise<void>& ready);
  void vision_main(std::promise<void>& ready);
  void run_cycle(FrameSlot& slot, CycleResult& out);
  void hand_over_calibration_image(const FrameSlot& slot, CycleResult& out);
  static bool start_result(const FrameSlot& slot, CycleResult::Kind kind, CycleResult& out);
  // pipeline_result_'s candidates into out (robot-base picks with the camera on base_T_flange when
  // given) and the pick choice's view of them into `choice`; returns their number.
  int fill_candidates(const Eigen::Isometry3d* base_T_flange,
                      std::array<motion::PickCandidate, CycleResult::kMaxCandidates>& choice, CycleResult& out) const;
  // After a first look (cell_look.cpp): asks for a second when config second_look says so, and
  // keeps the first look's result for it (no pick is published then).
  void plan_look(const CycleRequest& request, CycleResult& out);
  // A second look: the frames in `in` fused with the first look kept by plan_look, into pipeline_result_.
  void fuse_look(const VisionInput& in, const CycleRequest& request);
  // cell_grip.cpp. Acquisition thread: makes the gripper camera (config gripper_check) and the
  // slots' images for it; takes one into slot.gripper (throws on failure).
  void start_gripper_camera();
  void capture_gripper(FrameSlot& slot);
  // Vision thread: the gripper check of slot.gripper into out.
  void check_grip(const FrameSlot& slot, CycleResult& out);
  // The eligible candidates in pick order into out.ranked; out.chosen the first.
  void rank_picks(std::span<const motion::PickCandidate> choice, CycleResult& out) const;
  void serve_snapshot_requests();
  // Saves the kept cycle (retained_) and posts a SnapshotSaved result.
  void write_snapshot(const char* reason);
  // Queues a result for the main thread, waiting while its ring is full (off the frame path).
  void post_result(const CycleResult& result);

  DaemonConfig config_;
  VisionStageFactory vision_factory_;
  FrameSourceFactory source_factory_;

  motion::SpscRing<CycleRequest, 16> requests_;
  motion::SpscRing<FrameSlot, kFrameSlots> frames_;
  motion::SpscRing<CycleResult, kResultSlots> results_;
  struct SnapshotRequest {
    std::uint64_t cycle = 0;
    char reason[64] = {};
  };
  motion::SpscRing<SnapshotRequest, 8> snapshot_requests_;  // main -> vision
  UniqueFd acq_wake_, vision_wake_, result_fd_;
  std::atomic<bool> stop_{false};
  std::thread acquisition_, vision_;

  // Set by the threads before they report ready (the start() handshake orders them).
  std::unique_ptr<FrameSource> source_;            // owned by the acquisition thread
  std::unique_ptr<GripperCamera> gripper_camera_;  // acquisition thread; null without gripper_check
  // Real cameras: the camera file's lens distortion, removed from every image on its way into a
  // slot (maps computed once at start), except for calibration captures (raw: calibration fits or
  // removes the distortion itself). A no-op for the simulated cell (an ideal pinhole).
  vision::FrameUndistorter undistorter_;
  std::unique_ptr<VisionStage> stage_;  // owned by the vision thread
  std::string source_description_, vision_description_;
  std::vector<std::pair<int, std::string>> parts_;
  bool realtime_ = false;

  std::atomic<std::uint64_t> acq_beat_{0}, vision_beat_{0}, frames_dropped_{0};
  vision::PipelineResult pipeline_result_;     // vision thread; capacity reserved once
  vision::PipelineResult first_look_;          // vision thread: the first look a second look fuses with
  std::uint64_t first_look_cycle_ = 0;         // its cycle (0: none kept)
  RetainedJob retained_;                       // vision thread; allocated before the threads report ready
  std::unique_ptr<SnapshotWriter> snapshots_;  // vision thread; made with the stage
  LatestFrame web_frames_;                     // allocated before the threads report ready
  cv::Mat1b calibration_image_;                // allocated before the threads report ready
};

}  // namespace mfcd::daemon
