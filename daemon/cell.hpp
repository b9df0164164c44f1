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

#include "daemon/config.hpp"
#include "daemon/cycle.hpp"
#include "daemon/frame_source.hpp"
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

  Cell(DaemonConfig config, VisionStageFactory vision, FrameSourceFactory source = makeFrameSource);
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
  int resultFd() const { return resultFd_; }          // readable when results are queued
  CycleResult* beginResult() noexcept;                // drains the eventfd; nullptr when none
  void endResult() noexcept { results_.end_read(); }

  // Asks the vision worker to save the kept frame set of `cycle` (the last cycle it ran) as a
  // snapshot; the answer is a SnapshotSaved result, with an error when that cycle's frames are
  // no longer kept. False when the request queue is full.
  bool requestSnapshot(std::uint64_t cycle, const char* reason) noexcept;

  // The ambient image of the last CalibrationCapture (see CycleResult::Kind::CalibrationImage);
  // preallocated, written by the vision thread before it posts that result.
  const cv::Mat1b& calibrationImage() const { return calibrationImage_; }
  // The last cycle's images and result for the web view (written by the vision worker when
  // web.enabled; one reader at a time). Lives as long as the cell.
  LatestFrame* webFrames() { return &webFrames_; }

  const DaemonConfig& config() const { return config_; }
  const std::string& sourceDescription() const { return sourceDescription_; }
  const std::string& visionDescription() const { return visionDescription_; }
  const std::vector<std::pair<int, std::string>>& parts() const { return parts_; }
  bool realtime() const { return realtime_; }
  // Incremented by each thread at every wake-up (at least every 200 ms when idle); the main thread
  // sends the systemd watchdog only while both keep moving.
  std::uint64_t acquisitionHeartbeat() const { return acqBeat_.load(std::memory_order_relaxed); }
  std::uint64_t visionHeartbeat() const { return visionBeat_.load(std::memory_order_relaxed); }
  std::uint64_t framesDropped() const { return framesDropped_.load(std::memory_order_relaxed); }

 private:
  void acquisitionMain(std::promise<void>& ready);
  void visionMain(std::promise<void>& ready);
  void runCycle(FrameSlot& slot, CycleResult& out);
  void handOverCalibrationImage(const FrameSlot& slot, CycleResult& out);
  static bool startResult(const FrameSlot& slot, CycleResult::Kind kind, CycleResult& out);
  // pipelineResult_'s candidates into out (robot-base picks with the camera on base_T_flange when
  // given) and the pick choice's view of them into `choice`; returns their number.
  int fillCandidates(const Eigen::Isometry3d* base_T_flange,
                     std::array<motion::PickCandidate, CycleResult::kMaxCandidates>& choice, CycleResult& out) const;
  // After a first look (cell_look.cpp): asks for a second when config second_look says so, and
  // keeps the first look's result for it (no pick is published then).
  void planLook(const CycleRequest& request, CycleResult& out);
  // A second look: the frames in `in` fused with the first look kept by planLook, into pipelineResult_.
  void fuseLook(const VisionInput& in, const CycleRequest& request);
  // The eligible candidates in pick order into out.ranked; out.chosen the first.
  void rankPicks(std::span<const motion::PickCandidate> choice, CycleResult& out) const;
  void serveSnapshotRequests();
  // Saves the kept cycle (retained_) and posts a SnapshotSaved result.
  void writeSnapshot(const char* reason);
  // Queues a result for the main thread, waiting while its ring is full (off the frame path).
  void postResult(const CycleResult& result);

  DaemonConfig config_;
  VisionStageFactory visionFactory_;
  FrameSourceFactory sourceFactory_;

  motion::SpscRing<CycleRequest, 16> requests_;
  motion::SpscRing<FrameSlot, kFrameSlots> frames_;
  motion::SpscRing<CycleResult, kResultSlots> results_;
  struct SnapshotRequest {
    std::uint64_t cycle = 0;
    char reason[64] = {};
  };
  motion::SpscRing<SnapshotRequest, 8> snapshotRequests_;  // main -> vision
  int acqWake_ = -1, visionWake_ = -1, resultFd_ = -1;
  std::atomic<bool> stop_{false};
  std::thread acquisition_, vision_;

  // Set by the threads before they report ready (the start() handshake orders them).
  std::unique_ptr<FrameSource> source_;  // owned by the acquisition thread
  // Real cameras: the camera file's lens distortion, removed from every image on its way into a
  // slot (maps computed once at start), except for calibration captures (raw: calibration fits or
  // removes the distortion itself). A no-op for the simulated cell (an ideal pinhole).
  vision::FrameUndistorter undistorter_;
  std::unique_ptr<VisionStage> stage_;  // owned by the vision thread
  std::string sourceDescription_, visionDescription_;
  std::vector<std::pair<int, std::string>> parts_;
  bool realtime_ = false;

  std::atomic<std::uint64_t> acqBeat_{0}, visionBeat_{0}, framesDropped_{0};
  vision::PipelineResult pipelineResult_;      // vision thread; capacity reserved once
  vision::PipelineResult firstLook_;           // vision thread: the first look a second look fuses with
  std::uint64_t firstLookCycle_ = 0;           // its cycle (0: none kept)
  RetainedJob retained_;                       // vision thread; allocated before the threads report ready
  std::unique_ptr<SnapshotWriter> snapshots_;  // vision thread; made with the stage
  LatestFrame webFrames_;                      // allocated before the threads report ready
  cv::Mat1b calibrationImage_;                 // allocated before the threads report ready
};

}  // namespace mfcd::daemon
