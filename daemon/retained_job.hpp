#pragma once
// The last cycle's frame set, result and depth edges, kept by the vision worker after the cycle
// has ended so they can still be saved as a snapshot: at once (a requested snapshot, a failed
// cycle) or later, when the robot reports the pick it was given as failed (Modbus PICK_RESULT)
// before the next cycle replaces them. Every buffer is allocated once; keep() only copies.
#include <cstdint>

#include <opencv2/core.hpp>

#include "daemon/cycle.hpp"
#include "vision/edges/depth_edges.hpp"

namespace mfcd::daemon {

class RetainedJob {
 public:
  // Before the cell's threads run frames: buffers for images of `format`.
  void allocate(const hal::ImageFormat& format);
  // Vision worker, in two steps: the cycle's result before it is handed over (a fixed-size copy),
  // then, after, the slot's images and the edges (nullptr: none), into the preallocated buffers.
  // No allocation.
  void keep_result(const CycleResult& result);
  void keep_frames(const FrameSlot& slot, const vision::DepthEdges* edges);
  // True when the kept cycle is `cycle`.
  bool holds(std::uint64_t cycle) const { return valid_ && result_.request.cycle_id == cycle; }
  std::uint64_t cycle() const { return valid_ ? result_.request.cycle_id : 0; }

  const FrameSlot& slot() const { return slot_; }
  const CycleResult& result() const { return result_; }
  // The cycle's depth edges; nullptr when it had none (capture or vision failed).
  const cv::Mat1b* edges() const { return have_edges_ ? &edges_ : nullptr; }

 private:
  FrameSlot slot_;
  CycleResult result_;
  cv::Mat1b edges_;
  bool have_edges_ = false;
  bool valid_ = false;
};

}  // namespace mfcd::daemon
