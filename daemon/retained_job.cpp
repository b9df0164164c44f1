#include "daemon/retained_job.hpp"

namespace mfcd::daemon {

void RetainedJob::allocate(const hal::ImageFormat& format) {
  slot_.allocate(format);
  edges_.create(format.height, format.width);
  edges_ = 0;  // resident from the start, as the zero-filled images are
  valid_ = false;
}

void RetainedJob::keep_result(const CycleResult& result) {
  result_ = result;
  valid_ = false;  // until its frames are kept too
}

void RetainedJob::keep_frames(const FrameSlot& slot, const vision::DepthEdges* edges) {
  copy_frame_set(slot.frames, slot_.frames);
  slot_.request = slot.request;
  slot_.ok = slot.ok;
  copy_message(slot_.error, sizeof slot_.error, slot.error);
  slot_.capture_ms = slot.capture_ms;
  slot_.captured = slot.captured;
  slot_.truth = slot.truth;
  slot_.leds_after = slot.leds_after;
  // Same size and type as the preallocated buffer: copyTo writes into it.
  have_edges_ = edges && !edges->edges.empty() && edges->edges.size() == edges_.size();
  if (have_edges_) edges->edges.copyTo(edges_);
  valid_ = true;
}

}  // namespace mfcd::daemon
