// HIL tier: the HAL against real kernel drivers in the test VM (tests/hil/run-vm.sh):
//   vivid    — V4L2 capture driver with error-injection controls   (/dev/video0)
//   gpio-sim — simulated GPIO chip "mfc-leds" with 8 lines; sysfs sim_gpioN/value shows what a
//              consumer drives, like a logic analyser on the LED lines
// Outside the VM the drivers are absent and every test skips; inside it (MFC_HIL=1) a missing
// driver is a failure.
#include <gpiod.h>
#include <gtest/gtest.h>
#include <fcntl.h>
#include <glob.h>
#include <linux/videodev2.h>
#include <signal.h>
#include <spawn.h>
#include <sys/ioctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "../hal/alloc_counter.hpp"
#include "mfcd/hal/clock.hpp"
#include "mfcd/hal/error.hpp"
#include "mfcd/hal/gpiod_light_ring.hpp"
#include "mfcd/hal/sequencer.hpp"
#include "mfcd/hal/v4l2_camera.hpp"

extern char** environ;

namespace mfcd::hal {
namespace {

constexpr const char* kVideo = "/dev/video0";
constexpr const char* kChipLabel = "mfc-leds";
// vivid's private controls (drivers/media/test-drivers/vivid/vivid-ctrls.c, VIVID_CID_VIVID_BASE + n;
// `v4l2-ctl -L` in the VM lists them with these ids).
constexpr std::uint32_t kVividTimestampSource = 0x00f0f018;  // 0 end of frame, 1 start of exposure
constexpr std::uint32_t kVividPercentDropped = 0x00f0f040;
constexpr std::uint32_t kVividDisconnect = 0x00f0f041;
constexpr std::uint32_t kVividInjectBufError = 0x00f0f042;
constexpr std::uint32_t kVividInjectStreamOnError = 0x00f0f045;
constexpr std::uint32_t kVividInjectFatalError = 0x00f0f046;
constexpr int kWidth = 320, kHeight = 180;  // one of vivid's webcam sizes

bool in_vm() { return std::getenv("MFC_HIL") != nullptr; }

#define REQUIRE_DRIVER(present, what)                                            \
  do {                                                                           \
    if (!(present)) {                                                            \
      if (in_vm()) FAIL() << what << " missing inside the HIL VM";                \
      GTEST_SKIP() << what << " not present (run the HIL tier: tools/mfc hil)"; \
    }                                                                            \
  } while (0)

bool vivid_present() {
  const int fd = ::open(kVideo, O_RDWR | O_CLOEXEC);
  if (fd < 0) return false;
  v4l2_capability cap{};
  const bool ok = ::ioctl(fd, VIDIOC_QUERYCAP, &cap) == 0 && std::string(reinterpret_cast<char*>(cap.driver)) == "vivid";
  ::close(fd);
  return ok;
}

bool sim_chip_present() {
  gpiod_chip* chip = gpiod_chip_open_by_label(kChipLabel);
  if (!chip) return false;
  gpiod_chip_close(chip);
  return true;
}

// Sets a control through a separate file handle, as another program would.
void vivid_control(std::uint32_t id, std::int32_t value) {
  const int fd = ::open(kVideo, O_RDWR | O_CLOEXEC);
  ASSERT_GE(fd, 0) << std::strerror(errno);
  v4l2_control c{id, value};
  EXPECT_EQ(::ioctl(fd, VIDIOC_S_CTRL, &c), 0) << "control 0x" << std::hex << id << ": " << std::strerror(errno);
  ::close(fd);
}

std::int32_t read_control(std::uint32_t id) {
  const int fd = ::open(kVideo, O_RDWR | O_CLOEXEC);
  v4l2_control c{id, 0};
  EXPECT_EQ(::ioctl(fd, VIDIOC_G_CTRL, &c), 0) << std::strerror(errno);
  ::close(fd);
  return c.value;
}

V4L2CameraConfig vivid_config(int bits = 8) {
  V4L2CameraConfig cfg;
  cfg.device = kVideo;
  cfg.width = kWidth;
  cfg.height = kHeight;
  cfg.bits_per_pixel = bits;
  cfg.frame_rate = 30;
  cfg.dequeue_timeout = std::chrono::milliseconds(1500);
  cfg.reconnect_backoff_min = std::chrono::milliseconds(50);
  return cfg;
}

// gpio-sim's view of the lines: /sys/devices/platform/gpio-sim.N/<chip>/sim_gpioK/value.
class SimLines {
public:
  explicit SimLines(const std::string& chip_name) {
    for (int i = 0; i < kLedCount; ++i) {
      glob_t g{};
      const std::string pattern = "/sys/devices/platform/gpio-sim.*/" + chip_name + "/sim_gpio" + std::to_string(i) + "/value";
      if (::glob(pattern.c_str(), 0, nullptr, &g) == 0 && g.gl_pathc == 1) fds_[static_cast<std::size_t>(i)] = ::open(g.gl_pathv[0], O_RDONLY | O_CLOEXEC);
      ::globfree(&g);
    }
  }
  ~SimLines() {
    for (int fd : fds_)
      if (fd >= 0) ::close(fd);
  }
  bool ok() const {
    for (int fd : fds_)
      if (fd < 0) return false;
    return true;
  }
  // Physical line levels as a mask (bit i = line offset i high). No allocation: usable while counting.
  LedMask read() const {
    LedMask m = 0;
    for (int i = 0; i < kLedCount; ++i) {
      char c = 0;
      if (::pread(fds_[static_cast<std::size_t>(i)], &c, 1, 0) == 1 && c == '1') m = static_cast<LedMask>(m | (1u << i));
    }
    return m;
  }

private:
  std::array<int, kLedCount> fds_{-1, -1, -1, -1, -1, -1, -1, -1};
};

std::string chip_name_of(const char* label) {
  gpiod_chip* chip = gpiod_chip_open_by_label(label);
  if (!chip) return {};
  std::string name = gpiod_chip_name(chip);
  gpiod_chip_close(chip);
  return name;
}

// ------------------------------------------------------------------------------------------ camera

class VividCamera : public ::testing::Test {
protected:
  void SetUp() override {
    REQUIRE_DRIVER(vivid_present(), "vivid at /dev/video0");
    vivid_control(kVividPercentDropped, 0);
    // vivid computes end-of-frame stamps as stream start + n * period, which can lie ahead of the
    // moment the buffer is delivered; start-of-exposure stamps are taken when the frame is made.
    vivid_control(kVividTimestampSource, 1);
  }
};

TEST_F(VividCamera, StreamsGreyFramesWithMonotonicTimestampsAndSequence) {
  for (int bits : {8, 16}) {
    SCOPED_TRACE(std::to_string(bits) + "-bit");
    V4L2Camera camera(vivid_config(bits));
    camera.configure();
    EXPECT_EQ(camera.format(), (ImageFormat{kWidth, kHeight, bits}));
    EXPECT_EQ(camera.driver(), "vivid");
    camera.activate();
    Image img(camera.format());
    FrameInfo info, previous;
    for (int n = 0; n < 8; ++n) {
      camera.read(img, info);
      const std::int64_t now = monotonic_now_ns();
      EXPECT_LE(info.timestamp_ns, now);
      EXPECT_GT(info.timestamp_ns, now - 2'000'000'000) << "timestamp not on CLOCK_MONOTONIC";
      if (n > 0) {
        EXPECT_GT(info.timestamp_ns, previous.timestamp_ns);
        EXPECT_GT(info.sequence, previous.sequence);
      }
      previous = info;
    }
    // vivid's default pattern is colour bars: the grey image is not flat.
    int lo = 65535, hi = 0;
    for (int x = 0; x < kWidth; x += 4) {
      const int v = bits == 8 ? img.row(kHeight / 2)[x] : reinterpret_cast<const std::uint16_t*>(img.row(kHeight / 2))[x];
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
    EXPECT_GT(hi - lo, bits == 8 ? 50 : 50 * 256);
    EXPECT_EQ(camera.stats().frames, 8u);
    EXPECT_EQ(camera.exposure_lead_ns(), 0) << "start-of-exposure stamps need no lead";
    camera.deactivate();
  }
}

TEST_F(VividCamera, EndOfFrameStampsGiveAFramePeriodOfLead) {
  vivid_control(kVividTimestampSource, 0);
  V4L2Camera camera(vivid_config());
  camera.configure();
  EXPECT_NEAR(static_cast<double>(camera.exposure_lead_ns()), 1e9 / 30, 1e6) << "frame period at 30 fps";
  vivid_control(kVividTimestampSource, 1);
}

TEST_F(VividCamera, AppliesManualGainWhereTheDeviceHasIt) {
  V4L2CameraConfig cfg = vivid_config();
  cfg.gain = 42;
  cfg.exposure_us = 5000;  // vivid has no exposure control: logged, not applied
  {
    V4L2Camera camera(cfg);
    camera.configure();
    EXPECT_TRUE(camera.gain_applied());
    EXPECT_FALSE(camera.exposure_applied());
    EXPECT_EQ(read_control(V4L2_CID_AUTOGAIN), 0);
    EXPECT_EQ(read_control(V4L2_CID_GAIN), 42);
  }
  cfg.gain = 1000;  // outside 0..255
  V4L2Camera bad(cfg);
  try {
    bad.configure();
    FAIL() << "gain out of range accepted";
  } catch (const HalError& e) {
    EXPECT_NE(std::string(e.what()).find("gain 1000"), std::string::npos) << e.what();
  }
  vivid_control(V4L2_CID_AUTOGAIN, 1);
}

TEST_F(VividCamera, UnsupportedSizeNamesTheDeviceAndWhatItOffers) {
  V4L2CameraConfig cfg = vivid_config();
  cfg.width = 123;
  cfg.height = 77;
  V4L2Camera camera(cfg);
  try {
    camera.configure();
    FAIL() << "odd size accepted";
  } catch (const HalError& e) {
    EXPECT_EQ(e.code(), ErrorCode::UnsupportedFormat);
    const std::string msg = e.what();
    EXPECT_NE(msg.find(kVideo), std::string::npos) << msg;
    EXPECT_NE(msg.find("123x77"), std::string::npos) << msg;
    EXPECT_NE(msg.find("--list-formats-ext"), std::string::npos) << msg;
  }
}

TEST_F(VividCamera, ErrorBuffersAreRequeuedAndStreamingContinues) {
  V4L2Camera camera(vivid_config());
  camera.configure();
  camera.activate();
  Image img(camera.format());
  FrameInfo info;
  camera.read(img, info);
  vivid_control(kVividInjectBufError, 1);
  for (int n = 0; n < 6; ++n) camera.read(img, info);
  EXPECT_GE(camera.stats().error_buffers, 1u);
  EXPECT_EQ(camera.stats().frames, 7u);
}

TEST_F(VividCamera, DroppedBuffersAreCountedFromSequenceGaps) {
  V4L2Camera camera(vivid_config());
  camera.configure();
  camera.activate();
  Image img(camera.format());
  FrameInfo info;
  vivid_control(kVividPercentDropped, 50);
  for (int n = 0; n < 12; ++n) camera.read(img, info);
  vivid_control(kVividPercentDropped, 0);
  EXPECT_GT(camera.stats().dropped_frames, 0u);
}

TEST_F(VividCamera, WatchdogReportsTimeoutAndStreamRecovers) {
  V4L2CameraConfig cfg = vivid_config();
  cfg.dequeue_timeout = std::chrono::milliseconds(400);
  V4L2Camera camera(cfg);
  camera.configure();
  camera.activate();
  Image img(camera.format());
  FrameInfo info;
  camera.read(img, info);
  vivid_control(kVividPercentDropped, 100);  // vivid stops returning buffers
  try {
    for (int n = 0; n < 10; ++n) camera.read(img, info);  // at most the frames already queued
    FAIL() << "no timeout";
  } catch (const HalError& e) {
    EXPECT_EQ(e.code(), ErrorCode::StreamTimeout);
    EXPECT_NE(std::string(e.what()).find(kVideo), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("400 ms"), std::string::npos) << e.what();
  }
  vivid_control(kVividPercentDropped, 0);
  const std::int64_t before = info.timestamp_ns;
  camera.read(img, info);  // restarts the stream first
  EXPECT_EQ(camera.stats().timeouts, 1u);
  EXPECT_GT(info.timestamp_ns, before);
}

TEST_F(VividCamera, StreamOnFailureNamesTheIoctlAndRetrySucceeds) {
  V4L2Camera camera(vivid_config());
  camera.configure();
  vivid_control(kVividInjectStreamOnError, 1);
  try {
    camera.activate();
    FAIL() << "injected STREAMON error not reported";
  } catch (const HalError& e) {
    EXPECT_NE(std::string(e.what()).find("VIDIOC_STREAMON"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(kVideo), std::string::npos) << e.what();
  }
  camera.activate();
  Image img(camera.format());
  FrameInfo info;
  camera.read(img, info);
}

TEST_F(VividCamera, FatalStreamingErrorIsReportedAndStreamRestarts) {
  V4L2Camera camera(vivid_config());
  camera.configure();
  camera.activate();
  Image img(camera.format());
  FrameInfo info;
  camera.read(img, info);
  vivid_control(kVividInjectFatalError, 1);
  bool failed = false;
  for (int n = 0; n < 6 && !failed; ++n) {
    try {
      camera.read(img, info);
    } catch (const HalError& e) {
      failed = true;
      EXPECT_EQ(e.code(), ErrorCode::Io);
      EXPECT_NE(std::string(e.what()).find("restarting"), std::string::npos) << e.what();
    }
  }
  EXPECT_TRUE(failed) << "fatal streaming error not reported";
  camera.read(img, info);
}

TEST_F(VividCamera, UnplugIsDetectedAndTheCameraReconnects) {
  V4L2Camera camera(vivid_config());
  camera.configure();
  camera.activate();
  Image img(camera.format());
  FrameInfo info;
  camera.read(img, info);
  vivid_control(kVividDisconnect, 1);  // emulates a USB unplug; back once every handle is closed
  try {
    for (int n = 0; n < 10; ++n) camera.read(img, info);
    FAIL() << "disconnect not detected";
  } catch (const HalError& e) {
    EXPECT_EQ(e.code(), ErrorCode::DeviceGone) << e.what();
    EXPECT_NE(std::string(e.what()).find(kVideo), std::string::npos) << e.what();
  }
  // The caller keeps calling read(); the camera reopens with backoff.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  bool back = false;
  int gone = 0;
  while (!back && std::chrono::steady_clock::now() < deadline) {
    try {
      camera.read(img, info);
      back = true;
    } catch (const HalError& e) {
      ASSERT_EQ(e.code(), ErrorCode::DeviceGone) << e.what();
      ++gone;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  EXPECT_TRUE(back) << "camera did not reconnect";
  EXPECT_EQ(camera.stats().reconnects, 1u);
  RecordProperty("reads_while_gone", gone);
}

// -------------------------------------------------------------------------------------- LED lines

class GpioSim : public ::testing::Test {
protected:
  void SetUp() override {
    REQUIRE_DRIVER(sim_chip_present(), "gpio-sim chip 'mfc-leds'");
    chip_name_ = chip_name_of(kChipLabel);
    lines_ = std::make_unique<SimLines>(chip_name_);
    ASSERT_TRUE(lines_->ok()) << "gpio-sim sysfs attributes for " << chip_name_ << " not found";
  }
  std::string chip_name_;
  std::unique_ptr<SimLines> lines_;
};

TEST_F(GpioSim, DrivesEachLedAloneInOrderAndAllOffAtTheEnd) {
  GpiodLightRing ring({kChipLabel, {0, 1, 2, 3, 4, 5, 6, 7}, false, "mfcd-hil"});
  ring.configure();
  EXPECT_EQ(ring.chip_label(), kChipLabel);
  EXPECT_EQ(lines_->read(), 0);
  ring.activate();
  for (int i = 0; i < kLedCount; ++i) {
    ring.set(static_cast<LedMask>(1u << i));
    EXPECT_EQ(lines_->read(), LedMask(1u << i)) << "LED " << i;
  }
  ring.set(0xA5);
  EXPECT_EQ(lines_->read(), 0xA5);
  ring.deactivate();
  EXPECT_EQ(lines_->read(), 0);
  EXPECT_THROW(ring.set(1), HalError);
}

TEST_F(GpioSim, ActiveLowAndOffsetMapping) {
  {
    GpiodLightRing ring({chip_name_, {7, 6, 5, 4, 3, 2, 1, 0}, true, "mfcd-hil"});  // by name this time
    ring.configure();
    EXPECT_EQ(lines_->read(), 0xFF) << "active-low LEDs are off with the lines high";
    ring.activate();
    ring.set(0x01);  // LED 0 sits on line 7
    EXPECT_EQ(lines_->read(), 0x7F);
    ring.set(0x06);  // LEDs 1 and 2 → lines 6 and 5
    EXPECT_EQ(lines_->read(), 0x9F);
    ring.deactivate();
    EXPECT_EQ(lines_->read(), 0xFF);
  }
}

TEST_F(GpioSim, WrongChipAndWrongOffsetsAreNamed) {
  {
    GpiodLightRing ring({"no-such-chip", {0, 1, 2, 3, 4, 5, 6, 7}, false, "mfcd-hil"});
    try {
      ring.configure();
      FAIL();
    } catch (const HalError& e) {
      EXPECT_EQ(e.code(), ErrorCode::DeviceMissing);
      EXPECT_NE(std::string(e.what()).find("no-such-chip"), std::string::npos) << e.what();
    }
  }
  for (auto offsets : {std::array<unsigned, 8>{0, 1, 2, 3, 4, 5, 6, 8}, std::array<unsigned, 8>{0, 1, 2, 3, 4, 5, 6, 6}}) {
    GpiodLightRing ring({kChipLabel, offsets, false, "mfcd-hil"});
    try {
      ring.configure();
      FAIL();
    } catch (const HalError& e) {
      EXPECT_EQ(e.code(), ErrorCode::WrongLine);
      const std::string msg = e.what();
      EXPECT_NE(msg.find("LED 7"), std::string::npos) << msg;
      EXPECT_NE(msg.find(kChipLabel), std::string::npos) << msg;
      EXPECT_NE(msg.find("gpioinfo"), std::string::npos) << msg;
    }
  }
  EXPECT_EQ(lines_->read(), 0);
}

TEST_F(GpioSim, LineHeldByAnotherProcessIsReportedThenRecovered) {
  // Another program (gpioset) holds line 3 high.
  pid_t pid = -1;
  char arg0[] = "gpioset", arg1[] = "--mode=signal", arg3[] = "3=1";
  std::string chip = kChipLabel;
  char* argv[] = {arg0, arg1, chip.data(), arg3, nullptr};
  ASSERT_EQ(::posix_spawnp(&pid, "gpioset", nullptr, nullptr, argv, environ), 0) << "gpioset (package gpiod) not found";
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (!(lines_->read() & 0x08) && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  ASSERT_EQ(lines_->read(), 0x08) << "gpioset did not take line 3";

  GpiodLightRing ring({kChipLabel, {0, 1, 2, 3, 4, 5, 6, 7}, false, "mfcd-hil"});
  try {
    ring.configure();
    FAIL() << "busy line not reported";
  } catch (const HalError& e) {
    EXPECT_EQ(e.code(), ErrorCode::LineBusy);
    const std::string msg = e.what();
    EXPECT_NE(msg.find("line 3 (LED 3) held by consumer \"gpioset\""), std::string::npos) << msg;
    EXPECT_NE(msg.find(kChipLabel), std::string::npos) << msg;
  }
  EXPECT_EQ(lines_->read(), 0x08) << "the failed request must not leave other lines driven";
  ::kill(pid, SIGTERM);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ring.configure();  // recovery: the line is free now
  ring.activate();
  ring.set(0x08);
  EXPECT_EQ(lines_->read(), 0x08);
}

// -------------------------------------------------------------------------- sequencer end to end

TEST(HilSequencer, EightLedsInLockstepWithVividFrames) {
  REQUIRE_DRIVER(vivid_present(), "vivid at /dev/video0");
  REQUIRE_DRIVER(sim_chip_present(), "gpio-sim chip 'mfc-leds'");
  vivid_control(kVividPercentDropped, 0);
  vivid_control(kVividTimestampSource, 1);  // see VividCamera::SetUp
  const std::string chip_name = chip_name_of(kChipLabel);
  SimLines lines(chip_name);
  ASSERT_TRUE(lines.ok());

  V4L2Camera camera(vivid_config());
  GpiodLightRing ring({kChipLabel, {0, 1, 2, 3, 4, 5, 6, 7}, false, "mfcd-hil"});
  MfcSequencer sequencer(camera, ring);
  sequencer.configure();
  sequencer.activate();

  // A logic analyser on the lines: a thread samples gpio-sim's sysfs and records every change.
  struct Edge {
    std::int64_t t;
    LedMask mask;
  };
  std::vector<Edge> edges;
  edges.reserve(4096);
  std::atomic<bool> stop{false}, running{false};
  std::int64_t max_gap_ns = 0;
  // The eight sysfs reads are not one atomic snapshot: a mask counts only once two scans in a row
  // agree, which filters scans straddling a switch (LED pulses last a frame, switches microseconds).
  std::thread sampler([&] {
    LedMask last = lines.read(), candidate = last;
    std::int64_t prev = monotonic_now_ns();
    running = true;
    while (!stop.load(std::memory_order_relaxed)) {
      const LedMask m = lines.read();
      const std::int64_t now = monotonic_now_ns();
      max_gap_ns = std::max(max_gap_ns, now - prev);
      prev = now;
      if (m == candidate && m != last && edges.size() < edges.capacity()) {
        edges.push_back({now, m});
        last = m;
      }
      candidate = m;
    }
  });
  while (!running) std::this_thread::yield();
  constexpr int kSets = 4;  // the first one warms up and is not counted for allocations
  std::array<std::uint64_t, kSets> sequences{};
  std::array<std::array<std::int64_t, 4>, kSets * FrameSet::kSlots> timing{};  // on, off, timestamp, led
  std::uint64_t allocs_before = 0;
  for (int s = 0; s < kSets; ++s) {
    if (s == 1) allocs_before = test::allocation_count();
    const FrameSet& set = sequencer.read();
    for (int k = 0; k < FrameSet::kSlots; ++k) {
      const SlotFrame& f = set.frames[static_cast<std::size_t>(k)];
      timing[static_cast<std::size_t>(s * FrameSet::kSlots + k)] = {f.on_ns, f.off_ns, f.info.timestamp_ns, f.led};
    }
    sequences[static_cast<std::size_t>(s)] = set.sequence;
  }
  const std::uint64_t allocs = test::allocation_count() - allocs_before;
  stop = true;
  sampler.join();
  sequencer.deactivate();
  EXPECT_EQ(lines.read(), 0) << "LEDs left on after deactivate()";
  EXPECT_EQ(allocs, 0u) << "steady-state FrameSet capture allocated";

  for (int s = 0; s < kSets; ++s) EXPECT_EQ(sequences[static_cast<std::size_t>(s)], static_cast<std::uint64_t>(s + 1));
  const std::int64_t lead = camera.exposure_lead_ns();
  for (const auto& [on, off, ts, led] : timing) {
    SCOPED_TRACE("LED " + std::to_string(led));
    EXPECT_GE(ts - lead, on) << "frame exposed before the LED went on";
    EXPECT_LE(ts, off) << "frame stamped after the LED went off";
  }

  // The lines did exactly: LED0, LED1, ..., LED7 per set, one LED at a time (the off gap between
  // two LEDs lasts microseconds and may fall between samples), and each LED was seen lit over its
  // frame's exposure. Debounced sampling delays an edge by at most two scan gaps.
  std::vector<std::size_t> rises_at;
  for (std::size_t e = 0; e < edges.size(); ++e) {
    EXPECT_LE(__builtin_popcount(edges[e].mask), 1) << "two LEDs on at once: mask 0x" << std::hex << int(edges[e].mask);
    if (edges[e].mask) rises_at.push_back(e);
  }
  ASSERT_EQ(rises_at.size(), static_cast<std::size_t>(kSets * kLedCount)) << "sampler missed or saw extra pulses";
  for (std::size_t pulse = 0; pulse < rises_at.size(); ++pulse) {
    const std::size_t e = rises_at[pulse];
    ASSERT_EQ(edges[e].mask, LedMask(1u << (pulse % kLedCount))) << "pulse " << pulse << " out of order";
    ASSERT_LT(e + 1, edges.size()) << "last LED never seen off";
    const std::int64_t rise = edges[e].t, fall = edges[e + 1].t;
    const auto& [on, off, ts, led] = timing[pulse / kLedCount * FrameSet::kSlots + pulse % kLedCount];
    EXPECT_LE(rise, ts - lead + 2 * max_gap_ns) << "LED " << led << " seen on only after its exposure began";
    EXPECT_GE(fall, ts) << "LED " << led << " seen off before its frame was stamped";
  }
  RecordProperty("sampler_max_gap_us", static_cast<int>(max_gap_ns / 1000));
  std::printf("sequencer: %d sets, %zu pulses, sampler max gap %.1f us, %llu stale frames discarded, %llu camera drops\n",
              kSets, rises_at.size(), max_gap_ns / 1e3, static_cast<unsigned long long>(sequencer.stats().stale_discarded),
              static_cast<unsigned long long>(camera.stats().dropped_frames));
}

}  // namespace
}  // namespace mfcd::hal
