// The frame path in process: Cell (acquisition + vision threads, SPSC rings) on the simulated
// camera with the HAL's pattern scene, and a test backend below VisionStage. Budget, deadline,
// degraded and overrun accounting; no allocation in steady state; CycleStats against a reference.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>

#include <poll.h>
#include <unistd.h>

#include "../hal/alloc_counter.hpp"
#include "daemon/cell.hpp"
#include "daemon/cycle_stats.hpp"
#include "run_cycle.hpp"
#include "test_vision_stage.hpp"
#include "vision/camera/camera.hpp"
#include "vision/camera/frame_undistorter.hpp"

using namespace mfcd::daemon;
using namespace std::chrono_literals;

namespace {

DaemonConfig pattern_config(int budget_ms) {
  // No recipe mesh: the simulated camera serves the HAL's test pattern (no OpenGL needed).
  DaemonConfig c = parse_config(
      "camera:\n  model: camera-sim.yaml\nrecipes:\n  - {id: 0, part: any, obj_id: 0}\n"
      "daemon:\n  realtime_priority: 0\n  cycle_budget_ms: " +
          std::to_string(budget_ms) + "\n",
      "test", {MFC_SOURCE_DIR "/config"});
  return c;
}

CycleRequest request(std::uint64_t id, int budget_ms) {
  CycleRequest r;
  r.origin = CycleOrigin::Benchmark;
  r.cycle_id = id;
  r.trigger = Clock::now();
  r.deadline = r.trigger + std::chrono::milliseconds(budget_ms) * 9 / 10;
  return r;
}

CycleResult run_one(Cell& cell, const CycleRequest& r) { return test::run_cycle(cell, r); }

// The next SnapshotSaved result (other kinds are skipped).
CycleResult next_snapshot(Cell& cell) {
  for (int i = 0; i < 100; ++i) {
    pollfd p{cell.result_fd(), POLLIN, 0};
    ::poll(&p, 1, 100);
    if (CycleResult* res = cell.begin_result()) {
      const CycleResult copy = *res;
      cell.end_result();
      if (copy.kind == CycleResult::Kind::SnapshotSaved) return copy;
    }
  }
  ADD_FAILURE() << "no snapshot result within 10 s";
  return {};
}

std::string read_file(const std::filesystem::path& file) {
  std::ifstream in(file);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

}  // namespace

TEST(Cycle, WithinBudgetNotDegradedNotOverrun) {
  const DaemonConfig config = pattern_config(1000);
  Cell cell(config, [](const DaemonConfig&) { return std::make_unique<test::TruthVisionStage>(30ms); });
  cell.start();
  const CycleResult r = run_one(cell, request(1, 1000));
  EXPECT_EQ(r.error, CycleError::None) << r.message;
  EXPECT_FALSE(r.degraded);
  EXPECT_GE(r.vision_ms, 29.0);
  EXPECT_GT(r.capture_ms, 0.0);
  EXPECT_GE(r.total_ms, r.capture_ms + r.vision_ms);
  EXPECT_TRUE(r.leds_off);
  CycleStats stats;
  EXPECT_FALSE(stats.add(r, 1000));
  EXPECT_EQ(stats.overruns(), 0u);
}

TEST(Cycle, DeadlineCutsTheVisionStageShortAndFlagsDegraded) {
  const DaemonConfig config = pattern_config(200);
  Cell cell(config, [](const DaemonConfig&) { return std::make_unique<test::TruthVisionStage>(2000ms); });
  cell.start();
  const auto t0 = Clock::now();
  const CycleResult r = run_one(cell, request(1, 200));
  const double wall = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  EXPECT_TRUE(r.degraded);
  EXPECT_LT(wall, 1000.0) << "the worker must not block for the backend's full 2 s";
  EXPECT_LT(r.total_ms, 400.0);
  CycleStats stats;
  stats.add(r, 200);
  EXPECT_EQ(stats.degraded(), 1u);
}

TEST(Cycle, ABackendIgnoringTheDeadlineIsCountedAsOverrun) {
  const DaemonConfig config = pattern_config(100);
  Cell cell(config, [](const DaemonConfig&) { return std::make_unique<test::TruthVisionStage>(250ms, false); });
  cell.start();
  const CycleResult r = run_one(cell, request(1, 100));
  EXPECT_FALSE(r.degraded);
  EXPECT_GT(r.total_ms, 250.0);
  CycleStats stats;
  EXPECT_TRUE(stats.add(r, 100));
  EXPECT_EQ(stats.overruns(), 1u);
}

TEST(Cycle, BackendFailureAtStartIsReportedAndThreadsJoined) {
  const DaemonConfig config = pattern_config(100);
  Cell cell(config, [](const DaemonConfig&) -> std::unique_ptr<VisionStage> {
    throw std::runtime_error("templates/x.tdb: corrupt");
  });
  try {
    cell.start();
    FAIL() << "start() should throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("vision: templates/x.tdb: corrupt"), std::string::npos) << e.what();
  }
}

// Heap allocations over 20 cycles of a started cell after 3 warm-up cycles; every cycle must
// succeed (a failed one is a test failure and counts as an allocation, so the check cannot pass).
static std::uint64_t steady_state_allocations(Cell& cell) {
  for (int i = 1; i <= 3; ++i) run_one(cell, request(static_cast<std::uint64_t>(i), 1000));  // warm-up
  const std::uint64_t before = mfcd::hal::test::allocation_count();
  std::uint64_t failed = 0;
  for (int i = 4; i < 24; ++i) {
    const CycleResult r = run_one(cell, request(static_cast<std::uint64_t>(i), 1000));
    if (r.error != CycleError::None) {
      ADD_FAILURE() << "cycle " << i << ": " << r.message;
      ++failed;
    }
  }
  return mfcd::hal::test::allocation_count() - before + failed;
}

TEST(Cycle, NoAllocationOnTheFramePathInSteadyState) {
  const DaemonConfig config = pattern_config(1000);
  Cell cell(config, [](const DaemonConfig&) { return std::make_unique<test::TruthVisionStage>(1ms); });
  cell.start();
  EXPECT_EQ(steady_state_allocations(cell), 0u) << "acquisition, copy into the ring, vision worker, results";
}

namespace {
// The simulated camera's frames served as if by a real camera (no SimulatedWorld), so the Cell
// undistorts them with the camera file's lens distortion.
class AsRealCamera final : public FrameSource {
 public:
  explicit AsRealCamera(std::unique_ptr<FrameSource> inner) : inner_(std::move(inner)) {}
  void activate() override { inner_->activate(); }
  void deactivate() noexcept override { inner_->deactivate(); }
  const mfcd::hal::FrameSet& capture() override { return inner_->capture(); }
  mfcd::hal::ImageFormat format() const override { return inner_->format(); }
  mfcd::hal::LedMask leds() const override { return inner_->leds(); }
  std::string describe() const override { return "as real: " + inner_->describe(); }

 private:
  std::unique_ptr<FrameSource> inner_;
};
}  // namespace

TEST(Cycle, NoAllocationOnTheFramePathInSteadyStateWithLensDistortion) {
  DaemonConfig config = pattern_config(1000);
  mfcd::vision::CameraConfig camera = mfcd::vision::load_camera_config(config.camera.model);
  camera.camera.distortion = {-0.2, 0.05, 0.001, -0.001, 0.0};
  const std::filesystem::path file =
      std::filesystem::temp_directory_path() / ("mfcd-cycle-distorted-" + std::to_string(::getpid()) + ".yaml");
  mfcd::vision::save_camera_config(camera, file);
  config.camera.model = file;
  Cell cell(
      config, [](const DaemonConfig&) { return std::make_unique<test::TruthVisionStage>(1ms); },
      [](const DaemonConfig& c) -> std::unique_ptr<FrameSource> {
        return std::make_unique<AsRealCamera>(make_frame_source(c));
      });
  cell.start();
  EXPECT_EQ(steady_state_allocations(cell), 0u) << "acquisition, undistortion into the ring, vision worker, results";
  cell.stop();
  std::filesystem::remove(file);
}

TEST(Cycle, UndistortingCopyRemapsEveryImageIntoTheSlotAndKeepsTheMetadata) {
  mfcd::vision::PinholeCamera cam;
  cam.image_size = {64, 48};
  cam.K = cv::Matx33d(60, 0, 31.5, 0, 60, 23.5, 0, 0, 1);
  cam.distortion = {-0.3, 0.1, 0, 0, 0};
  const mfcd::vision::FrameUndistorter undistorter(cam);
  ASSERT_TRUE(undistorter.active());
  const mfcd::hal::ImageFormat format{64, 48, 8};
  mfcd::hal::FrameSet from, to, expected;
  for (std::size_t k = 0; k < from.frames.size(); ++k) {
    from.frames[k].image.allocate(format);
    to.frames[k].image.allocate(format);
    for (int y = 0; y < 48; ++y)
      for (int x = 0; x < 64; ++x)
        from.frames[k].image.row(y)[x] = static_cast<std::uint8_t>((x * 4 + y * 3 + static_cast<int>(k) * 17) & 0xff);
    from.frames[k].led = static_cast<int>(k);
    from.frames[k].on_ns = 1000 + static_cast<std::int64_t>(k);
  }
  from.sequence = 42;
  const std::uint8_t* slot_data = to.frames[3].image.data();
  copy_frame_set(from, to, undistorter);
  EXPECT_EQ(to.sequence, 42u);
  EXPECT_EQ(to.frames[3].image.data(), slot_data) << "written in place";
  for (std::size_t k = 0; k < from.frames.size(); ++k) {
    EXPECT_EQ(to.frames[k].led, from.frames[k].led);
    EXPECT_EQ(to.frames[k].on_ns, from.frames[k].on_ns);
    const cv::Mat src(48, 64, CV_8UC1, from.frames[k].image.data());
    cv::Mat want;
    undistorter.apply(src, want);
    const cv::Mat got(48, 64, CV_8UC1, to.frames[k].image.data());
    EXPECT_EQ(cv::norm(got, want, cv::NORM_INF), 0.0) << "image " << k;
    EXPECT_GT(cv::norm(got, src, cv::NORM_INF), 10.0) << "image " << k << " was copied, not undistorted";
  }
}

// The soak's frame check (TruthVisionStage pattern mode, tools/mfc load --camera pattern): through
// the real Cell every frame set passes and yields one stand-in pick; frames that are not what the
// sequencer should have delivered are refused, each with a message naming the image.
TEST(Cycle, PatternCheckPassesTheRealFramePathAndPicksTheStandIn) {
  const DaemonConfig config = pattern_config(1000);
  Cell cell(config, [](const DaemonConfig&) { return std::make_unique<test::TruthVisionStage>(1ms, true, 0, true); });
  cell.start();
  for (int i = 1; i <= 5; ++i) {
    const CycleResult r = run_one(cell, request(static_cast<std::uint64_t>(i), 1000));
    ASSERT_EQ(r.error, CycleError::None) << r.message;
    ASSERT_EQ(r.candidate_count, 1);
    EXPECT_EQ(r.chosen, 0);
    EXPECT_TRUE(r.candidates[0].base_valid) << "the stand-in has a robot-base pose";
  }
}

TEST(Cycle, PatternCheckRefusesWrongLedStaleAndUntaggedFrames) {
  namespace hal = mfcd::hal;
  const hal::ImageFormat format{64, 8, 8};
  // One frame set as the sequencer exposes it: LED 0..7 alone, then the ambient (none lit).
  std::vector<hal::Image> images(hal::kLedCount + 1, hal::Image(format));
  const auto expose = [&](std::uint64_t first) {
    hal::PatternSceneRenderer pattern;
    for (int k = 0; k <= hal::kLedCount; ++k)
      pattern.render(k < hal::kLedCount ? hal::LedMask(1u << k) : hal::LedMask(0),
                     first + static_cast<std::uint64_t>(k), images[static_cast<std::size_t>(k)]);
  };
  mfcd::vision::MfcFrames frames;
  for (int k = 0; k < hal::kLedCount; ++k)
    frames.flash.push_back(cv::Mat1b(format.height, format.width, images[static_cast<std::size_t>(k)].data()));
  frames.ambient = cv::Mat1b(format.height, format.width, images.back().data());
  mfcd::vision::PipelineResult out;
  out.candidates.reserve(4);
  const auto process = [&](test::TruthVisionStage& stage) -> std::string {
    try {
      stage.process({frames, 0, Clock::now() + 1s, nullptr}, out);
      return "";
    } catch (const std::runtime_error& e) {
      return e.what();
    }
  };
  {
    test::TruthVisionStage stage(0ms, true, 0, true);
    expose(100);
    EXPECT_EQ(process(stage), "");
    EXPECT_EQ(out.candidates.size(), 1u);
    expose(109);
    EXPECT_EQ(process(stage), "") << "the next set";
    EXPECT_NE(process(stage).find("flash0 has exposure index 109, not newer"), std::string::npos)
        << "the same set again: stale";
  }
  {
    test::TruthVisionStage stage(0ms, true, 0, true);
    expose(100);
    std::swap(frames.flash[2], frames.flash[3]);  // two slots crossed
    EXPECT_NE(process(stage).find("flash2 was exposed with LED mask 8, expected 4"), std::string::npos);
    std::swap(frames.flash[2], frames.flash[3]);
    frames.ambient(0, 0) = 0;  // no tag: a rendered (or torn) image
    EXPECT_NE(process(stage).find("ambient0 carries no test-pattern tag"), std::string::npos);
  }
}

// A pick reported failed after its cycle (Modbus PICK_RESULT): the kept frame set is saved until
// the next cycle replaces it, then the request is answered with the reason.
TEST(Cycle, KeptFrameSetIsSavedUntilTheNextCycleReplacesIt) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("mfcd-kept-" + std::to_string(::getpid()));
  DaemonConfig config = pattern_config(1000);
  config.snapshots.directory = dir;
  Cell cell(config, [](const DaemonConfig&) { return std::make_unique<test::TruthVisionStage>(5ms, true, 0, true); });
  cell.start();
  ASSERT_EQ(run_one(cell, request(1, 1000)).error, CycleError::None);
  ASSERT_TRUE(cell.request_snapshot(1, "pick result: missed (job 1, pick 1)"));
  const CycleResult saved = next_snapshot(cell);
  ASSERT_NE(saved.snapshot_dir[0], '\0') << saved.message;
  EXPECT_EQ(saved.request.cycle_id, 1u);
  const std::filesystem::path snap = saved.snapshot_dir;
  for (const char* f : {"test/000001/flash/000000_0.png", "test/000001/flash/000000_7.png",
                        "test/000001/ambient/000000.png", "overlay.png", "result.json"})
    EXPECT_TRUE(std::filesystem::exists(snap / f)) << f;
  const std::string json = read_file(snap / "result.json");
  EXPECT_NE(json.find("\"snapshot_reason\": \"pick result: missed (job 1, pick 1)\""), std::string::npos) << json;
  EXPECT_NE(json.find("\"cycle\": 1,"), std::string::npos);

  ASSERT_EQ(run_one(cell, request(2, 1000)).error, CycleError::None);
  ASSERT_TRUE(cell.request_snapshot(1, "late"));
  const CycleResult gone = next_snapshot(cell);
  EXPECT_EQ(gone.snapshot_dir[0], '\0');
  EXPECT_NE(std::string(gone.message).find("no longer kept (cycle 2 ran after it)"), std::string::npos) << gone.message;
  ASSERT_TRUE(cell.request_snapshot(2, "pick result: dropped"));
  EXPECT_NE(next_snapshot(cell).snapshot_dir[0], '\0');
  cell.stop();
  std::filesystem::remove_all(dir);
}

TEST(CycleStats, PercentilesMatchASortedReference) {
  std::mt19937 rng(3);
  for (int trial = 0; trial < 20; ++trial) {
    CycleStats stats;
    const int n = 1 + static_cast<int>(rng() % 3000);
    std::vector<float> all;
    for (int i = 0; i < n; ++i) {
      CycleResult r;
      r.total_ms = static_cast<float>(std::exponential_distribution<>(0.01)(rng));
      r.candidate_count = static_cast<int>(rng() % 4);
      stats.add(r, 150);
      all.push_back(static_cast<float>(r.total_ms));
    }
    // Reference: the last kWindow samples, sorted, nearest rank.
    std::vector<float> window(all.end() - std::min<std::ptrdiff_t>(n, CycleStats::kWindow), all.end());
    std::sort(window.begin(), window.end());
    for (double p : {0.0, 1.0, 50.0, 90.0, 99.0, 100.0}) {
      std::size_t k = static_cast<std::size_t>(std::ceil(p / 100 * static_cast<double>(window.size())));
      k = k == 0 ? 0 : k - 1;
      EXPECT_FLOAT_EQ(static_cast<float>(stats.percentile_ms(p)), window[k]) << "p" << p << " n " << n;
    }
    EXPECT_EQ(stats.overruns(),
              static_cast<std::uint64_t>(std::count_if(all.begin(), all.end(), [](float v) { return v > 150; })));
    EXPECT_EQ(stats.cycles(), static_cast<std::uint64_t>(n));
  }
}
