#pragma once
// A vision backend for tests, below the VisionStage interface (the real one is
// BinPickingPipeline, tested end to end in daemon_pipeline_e2e_test): it "finds" the parts of the
// simulated bin's ground truth, after `work` of busy time that it cuts short at the deadline,
// setting the degraded flag — the contract the real pipeline follows. It lets the daemon's
// threads, queue, budget accounting, robot link and control socket be tested independently of the
// matcher's accuracy.
#include <chrono>
#include <stdexcept>
#include <thread>

#include <opencv2/imgproc.hpp>

#include "daemon/vision_stage.hpp"

namespace mfcd::daemon::test {

class TruthVisionStage final : public VisionStage {
public:
  // failFirst: the first that many calls throw, as a failing vision stage does.
  explicit TruthVisionStage(std::chrono::milliseconds work, bool honourDeadline = true, int failFirst = 0)
      : work_(work), honourDeadline_(honourDeadline), failFirst_(failFirst) {}
  void process(const VisionInput& in, vision::PipelineResult& out) override {
    if (calls < failFirst_) {
      ++calls;
      throw std::runtime_error("injected vision failure (test backend)");
    }
    const auto start = Clock::now();
    auto until = start + work_;
    out.degraded = false;
    if (honourDeadline_ && in.deadline < until) {
      until = in.deadline;
      out.degraded = true;
    }
    std::this_thread::sleep_until(until);
    out.candidates.clear();
    if (in.truth) {
      for (int i = 0; i < in.truth->count && out.candidates.size() < out.candidates.capacity(); ++i) {
        const auto& p = in.truth->parts[static_cast<std::size_t>(i)];
        if (in.obj_id != 0 && p.obj_id != in.obj_id) continue;
        vision::PoseCandidate c;
        c.obj_id = p.obj_id;
        c.R_m2c = p.R;
        c.t_m2c_mm = p.t_mm;
        c.score = 0.9 - 0.01 * i;
        c.refined = true;
        out.candidates.push_back(c);
      }
    }
    out.times = {};
    out.times.search_ms = out.times.total_ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    // Edges: a cheap stand-in computed from the frames so snapshots have something to save.
    cv::absdiff(in.frames.flash[0], in.frames.ambient, edges_.edges);
    haveEdges_ = true;
    ++calls;
  }
  std::vector<std::pair<int, std::string>> parts() const override { return {{0, "truth"}}; }
  const vision::DepthEdges* lastEdges() const override { return haveEdges_ ? &edges_ : nullptr; }
  cv::Mat3b overlay(const cv::Mat1b& image, const vision::PipelineResult& result) const override {
    cv::Mat3b out;
    cv::cvtColor(image, out, cv::COLOR_GRAY2BGR);
    for (const auto& c : result.candidates) cv::circle(out, {320 + int(c.t_m2c_mm[0]), 240 + int(c.t_m2c_mm[1])}, 5, {0, 0, 255}, 2);
    return out;
  }
  std::string describe() const override { return "test backend: simulated ground truth"; }
  int calls = 0;

private:
  std::chrono::milliseconds work_;
  bool honourDeadline_;
  int failFirst_;
  vision::DepthEdges edges_;
  bool haveEdges_ = false;
};

}  // namespace mfcd::daemon::test
