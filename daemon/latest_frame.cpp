#include "daemon/latest_frame.hpp"

namespace mfcd::daemon {

void LatestFrame::allocate(cv::Size size) {
  for (WebFrame& f : buffers_) {
    for (cv::Mat1b* m : {&f.ambient, &f.composite, &f.edges}) {
      m->create(size);
      *m = 0;  // resident from the start
    }
    f.have_edges = false;
  }
}

void LatestFrame::publish(const FrameSlot& slot, const CycleResult& result, const cv::Mat1b* edges) noexcept {
  WebFrame& f = buffers_[back_];
  // Same sizes as allocated: copyTo and max write into the buffers.
  if (slot.mfc.ambient.size() != f.ambient.size()) return;
  slot.mfc.ambient.copyTo(f.ambient);
  slot.mfc.flash[0].copyTo(f.composite);
  cv::Mat composite = f.composite;  // a header over the buffer: max writes in place
  for (std::size_t k = 1; k < slot.mfc.flash.size(); ++k) cv::max(composite, cv::Mat(slot.mfc.flash[k]), composite);
  f.have_edges = edges && edges->size() == f.edges.size();
  if (f.have_edges) edges->copyTo(f.edges);
  f.result = result;
  // Release: the reader that sees kNew sees the buffer's contents.
  back_ = ready_.exchange(back_ | kNew, std::memory_order_acq_rel) & kIndex;
}

const WebFrame* LatestFrame::newest() noexcept {
  if (ready_.load(std::memory_order_acquire) & kNew) {
    front_ = ready_.exchange(front_, std::memory_order_acq_rel) & kIndex;
    any_ = true;
  }
  return any_ ? &buffers_[front_] : nullptr;
}

}  // namespace mfcd::daemon
