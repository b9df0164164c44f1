#pragma once
// The last cycle's images and result for the web view, handed from the vision worker to the web
// server's threads without a lock on the vision side: three preallocated buffers (a triple
// buffer). The writer fills its back buffer and swaps it with the "ready" one; the reader, when a
// newer frame is ready, swaps the one it holds with it. Neither side ever waits for the other,
// and the writer never allocates once allocate() has run.
#include <array>
#include <atomic>
#include <cstdint>

#include <opencv2/core.hpp>

#include "daemon/cycle.hpp"

namespace mfcd::daemon {

struct WebFrame {
  cv::Mat1b ambient;    // the ambient image
  cv::Mat1b composite;  // max over the flash images: every outline lit (the overlay's background)
  cv::Mat1b edges;      // the pipeline's depth edges; valid when have_edges
  bool have_edges = false;
  CycleResult result;  // the cycle's result (candidates, chosen, ranked)
};

class LatestFrame {
 public:
  // Before the writer runs: every buffer for images of `size`.
  void allocate(cv::Size size);

  // --- writer (one thread: the vision worker) ---
  // Fills the back buffer from the slot, its result and edges (nullptr: none), then publishes it.
  void publish(const FrameSlot& slot, const CycleResult& result, const cv::Mat1b* edges) noexcept;

  // --- reader (one thread at a time: the caller serialises readers) ---
  // The newest published frame, or nullptr before the first. Valid until the next call.
  const WebFrame* newest() noexcept;

 private:
  static constexpr unsigned kIndex = 3u, kNew = 4u;
  std::array<WebFrame, 3> buffers_;
  std::atomic<unsigned> ready_{2};  // index of the ready buffer, | kNew when the reader has not taken it
  unsigned back_ = 0;               // writer's
  unsigned front_ = 1;              // reader's
  bool any_ = false;                // reader's: a frame has been taken
};

}  // namespace mfcd::daemon
