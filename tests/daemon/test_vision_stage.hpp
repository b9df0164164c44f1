#pragma once
// A vision backend for tests, below the VisionStage interface (the real one is
// BinPickingPipeline, tested end to end in daemon_pipeline_e2e_test): it "finds" the parts of the
// simulated bin's ground truth, after `work` of busy time that it cuts short at the deadline,
// setting the degraded flag — the contract the real pipeline follows. It lets the daemon's
// threads, queue, budget accounting, robot link and control socket be tested independently of the
// matcher's accuracy.
//
// Pattern mode (check_pattern): the camera serves the HAL's test pattern (a simulated cell without
// meshes: no rendered bin, no ground truth). Every frame set is then checked instead: each image
// must carry the pattern's tag (PatternSceneRenderer) with the LED mask of its slot (flash i: LED i
// alone; ambient: none), and every exposure index of the set must be newer than all of the
// previous set's (a fresh capture, not a stale or reused ring slot); a mismatch throws, so the
// cycle fails with error code 3 (vision failed). Each cycle then reports one stand-in candidate, so
// pick choice, transform and publication run every cycle.
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <thread>

#include <opencv2/imgproc.hpp>

#include "daemon/vision_stage.hpp"
#include "mfcd/hal/simulated.hpp"

namespace mfcd::daemon::test {

class TruthVisionStage final : public VisionStage {
 public:
  // fail_first: the first that many calls throw, as a failing vision stage does.
  explicit TruthVisionStage(std::chrono::milliseconds work, bool honour_deadline = true, int fail_first = 0,
                            bool check_pattern = false)
      : work_(work), honour_deadline_(honour_deadline), fail_first_(fail_first), check_pattern_(check_pattern) {
    if (check_pattern_) {
      // The tag's magic byte as the HAL writes it (not restated here): one tiny rendered image.
      hal::Image probe(hal::ImageFormat{hal::PatternSceneRenderer::kTagPixels, 1, 8});
      hal::PatternSceneRenderer().render(1, 0, probe);
      tag_magic_ = probe.row(0)[0];
    }
  }
  void process(const VisionInput& in, vision::PipelineResult& out) override {
    if (calls < fail_first_) {
      ++calls;
      throw std::runtime_error("injected vision failure (test backend)");
    }
    if (check_pattern_) check_pattern_tags(in.frames);
    const auto start = Clock::now();
    auto until = start + work_;
    out.degraded = false;
    if (honour_deadline_ && in.deadline < until) {
      until = in.deadline;
      out.degraded = true;
    }
    std::this_thread::sleep_until(until);
    out.candidates.clear();
    if (check_pattern_ && out.candidates.capacity() > 0) {
      // Stand-in: one part lying flat 300 mm from the camera (mesh +z towards it), stepping 10 mm
      // along x from cycle to cycle so every published pick differs from the one before.
      vision::PoseCandidate c;
      c.obj_id = in.obj_id != 0 ? in.obj_id : 1;
      c.R_m2c = cv::Matx33d(1, 0, 0, 0, -1, 0, 0, 0, -1);
      c.t_m2c_mm = {-40.0 + 10.0 * (calls % 9), 0.0, 300.0};
      c.score = 0.9;
      c.refined = true;
      out.candidates.push_back(c);
    } else if (in.truth) {
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
    have_edges_ = true;
    ++calls;
  }
  std::vector<std::pair<int, std::string>> parts() const override { return {{0, "truth"}}; }
  const vision::DepthEdges* last_edges() const override { return have_edges_ ? &edges_ : nullptr; }
  cv::Mat3b overlay(const cv::Mat1b& image, const vision::PipelineResult& result) const override {
    cv::Mat3b out;
    cv::cvtColor(image, out, cv::COLOR_GRAY2BGR);
    for (const auto& c : result.candidates)
      cv::circle(out, {320 + int(c.t_m2c_mm[0]), 240 + int(c.t_m2c_mm[1])}, 5, {0, 0, 255}, 2);
    return out;
  }
  std::string describe() const override { return "test backend: simulated ground truth"; }
  int calls = 0;

 private:
  // Throws std::runtime_error naming the image and what is wrong with its tag. No allocation
  // unless it throws.
  void check_pattern_tags(const vision::MfcFrames& frames) {
    std::uint64_t newest = 0;
    const auto check = [&](const cv::Mat1b& image, unsigned want_lit, const char* name, int index) {
      if (image.cols < hal::PatternSceneRenderer::kTagPixels || image.rows < 1 || image(0, 0) != tag_magic_)
        throw std::runtime_error(std::string("test backend: ") + name + std::to_string(index) +
                                 " carries no test-pattern tag (not the pattern camera, or a torn frame)");
      const unsigned lit = image(0, 1);
      std::uint64_t exposure = 0;
      for (int b = 0; b < 8; ++b) exposure |= std::uint64_t{image(0, 2 + b)} << (8 * b);
      if (lit != want_lit)
        throw std::runtime_error(std::string("test backend: ") + name + std::to_string(index) +
                                 " was exposed with LED mask " + std::to_string(lit) + ", expected " +
                                 std::to_string(want_lit));
      if (have_previous_ && exposure <= previous_newest_)
        throw std::runtime_error(std::string("test backend: ") + name + std::to_string(index) + " has exposure index " +
                                 std::to_string(exposure) + ", not newer than the previous frame set's " +
                                 std::to_string(previous_newest_) + " (stale or reused frame)");
      newest = std::max(newest, exposure);
    };
    for (int i = 0; i < static_cast<int>(frames.flash.size()); ++i)
      check(frames.flash[static_cast<std::size_t>(i)], 1u << i, "flash", i);
    check(frames.ambient, 0u, "ambient", 0);
    previous_newest_ = newest;
    have_previous_ = true;
  }

  std::chrono::milliseconds work_;
  bool honour_deadline_;
  int fail_first_;
  bool check_pattern_;
  std::uint8_t tag_magic_ = 0;
  bool have_previous_ = false;
  std::uint64_t previous_newest_ = 0;
  vision::DepthEdges edges_;
  bool have_edges_ = false;
};

}  // namespace mfcd::daemon::test
