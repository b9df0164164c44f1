// AravisCamera against Aravis's own GigE Vision simulator, arv-fake-gv-camera-0.8 (Debian
// aravis-tools), on loopback: one fake camera per test, started as a child process with a serial of
// its own and reached by its camera id. The fake camera's diagonal ramp is known exactly, so every
// frame is checked pixel by pixel: Mono8 pixel (x, y) of frame id f is min(255, ((x + y + f) % 255)
// * s), Mono16 is min(65535, (256 (x + y + f) % 65535) * s), with s = 1 + gain + log10(exposure_us
// / 10000) (src/arvfakecamera.c). The fake camera is checked for with a raw GVCP discovery of our
// own (so a stranger on 127.0.0.1:3956 is noticed) and through Aravis's discovery; where either is
// impossible the tests skip, saying why.
#include <arpa/inet.h>
#include <arv.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "alloc_counter.hpp"
#include "catch_hal.hpp"
#include "mfcd/hal/aravis_camera.hpp"
#include "mfcd/hal/aravis_strobe_light_ring.hpp"
#include "mfcd/hal/error.hpp"
#include "mfcd/hal/sequencer.hpp"
#include "mfcd/hal/simulated.hpp"

extern "C" char** environ;

namespace mfcd::hal {
namespace {

using Clock = std::chrono::steady_clock;
constexpr const char* kFakeCameraProgram = "arv-fake-gv-camera-0.8";
constexpr int kWidth = 320, kHeight = 240;

std::optional<std::string> find_in_path(const std::string& program) {
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "/usr/bin:/bin");
  for (std::string dir; std::getline(dirs, dir, ':');) {
    const std::string candidate = (dir.empty() ? "." : dir) + "/" + program;
    if (::access(candidate.c_str(), X_OK) == 0) return candidate;
  }
  return std::nullopt;
}

using mfcd::hal::test::catch_hal;

bool mentions(const HalError& e, const std::string& text) {
  return std::string(e.what()).find(text) != std::string::npos;
}

// GVCP (GigE Vision control protocol) over UDP, just enough to see who answers on 127.0.0.1:3956
// without Aravis: DISCOVERY (the answer carries the bootstrap registers: serial at 0xd8).
class GvcpProbe {
 public:
  GvcpProbe() {
    fd_ = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_in any{};
    any.sin_family = AF_INET;
    any.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (fd_ >= 0) ::bind(fd_, reinterpret_cast<sockaddr*>(&any), sizeof any);
  }
  ~GvcpProbe() {
    if (fd_ >= 0) ::close(fd_);
  }
  GvcpProbe(const GvcpProbe&) = delete;
  GvcpProbe& operator=(const GvcpProbe&) = delete;

  // The serial number of whatever answers a discovery on 127.0.0.1:3956 within `wait`, if anything.
  std::optional<std::string> discover(std::chrono::milliseconds wait) {
    const std::uint8_t cmd[8] = {0x42, 0x01, 0x00, 0x02, 0x00, 0x00, 0x00, ++id_};
    if (!send(cmd, sizeof cmd)) return std::nullopt;
    std::uint8_t ack[8 + 0xf8];
    const auto n = receive(ack, sizeof ack, wait);
    if (n < 8 + 0xd8 + 16 || ack[2] != 0x00 || ack[3] != 0x03) return std::nullopt;
    const char* serial = reinterpret_cast<const char*>(ack + 8 + 0xd8);
    return std::string(serial, strnlen(serial, 16));
  }

  // READREG: a 32-bit bootstrap or device register, as the camera holds it (any host may read).
  std::optional<std::uint32_t> read_register(std::uint32_t address,
                                             std::chrono::milliseconds wait = std::chrono::milliseconds(500)) {
    const std::uint8_t tag = ++id_;
    // The packet's layout, header (8 bytes) then the register address (big-endian), stays by hand.
    // clang-format off
    const std::uint8_t cmd[12] = {0x42, 0x01, 0x00, 0x80, 0x00, 0x04, 0x00, tag,
                                  static_cast<std::uint8_t>(address >> 24), static_cast<std::uint8_t>(address >> 16),
                                  static_cast<std::uint8_t>(address >> 8), static_cast<std::uint8_t>(address)};
    // clang-format on
    if (!send(cmd, sizeof cmd)) return std::nullopt;
    std::uint8_t ack[12];
    for (;;) {  // skip late answers to earlier requests
      if (receive(ack, sizeof ack, wait) != 12) return std::nullopt;
      if (ack[2] == 0x00 && ack[3] == 0x81 && ack[7] == tag) break;
    }
    return std::uint32_t{ack[8]} << 24 | std::uint32_t{ack[9]} << 16 | std::uint32_t{ack[10]} << 8 | ack[11];
  }

 private:
  bool send(const std::uint8_t* data, std::size_t size) {
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_port = htons(3956);
    to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    return fd_ >= 0 &&
           ::sendto(fd_, data, size, 0, reinterpret_cast<sockaddr*>(&to), sizeof to) == static_cast<ssize_t>(size);
  }
  ssize_t receive(std::uint8_t* data, std::size_t size, std::chrono::milliseconds wait) {
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(wait.count())) <= 0) return -1;
    return ::recv(fd_, data, size, 0);
  }
  int fd_ = -1;
  std::uint8_t id_ = 0;
};

// arv-fake-gv-camera-0.8 as a child process; killed (SIGKILL) when the object goes.
class FakeCameraProcess {
 public:
  FakeCameraProcess(std::string program, std::string serial, std::vector<std::string> extra)
      : program_(std::move(program)), serial_(std::move(serial)), extra_(std::move(extra)) {
    log_ = "/tmp/mfcd-arv-fake-" + serial_ + ".log";
  }
  ~FakeCameraProcess() {
    kill();
    std::remove(log_.c_str());
  }
  FakeCameraProcess(const FakeCameraProcess&) = delete;
  FakeCameraProcess& operator=(const FakeCameraProcess&) = delete;

  // Starts the process and waits until it answers a GVCP discovery with our serial. Returns an
  // empty string, or why it did not come up (with the program's own output).
  std::string start(std::chrono::milliseconds wait = std::chrono::milliseconds(5000)) {
    std::vector<std::string> args{program_, "-i", "127.0.0.1", "-s", serial_};
    args.insert(args.end(), extra_.begin(), extra_.end());
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, log_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    const int rc = posix_spawn(&pid_, program_.c_str(), &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (rc != 0) {
      pid_ = -1;
      return "cannot start " + program_ + ": " + std::strerror(rc);
    }
    GvcpProbe probe;
    const auto until = Clock::now() + wait;
    while (Clock::now() < until) {
      if (probe.discover(std::chrono::milliseconds(200)) == serial_) return "";
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        return program_ + " exited at start (" + output() + ")";
      }
    }
    return program_ + " -i 127.0.0.1 did not answer a GVCP discovery on 127.0.0.1:3956 within " +
           std::to_string(wait.count()) + " ms (" + output() + ")";
  }
  void kill() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }
  std::string output() const {
    std::ifstream in(log_);
    std::stringstream s;
    s << in.rdbuf();
    std::string text = s.str();
    while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
    return text.empty() ? "no output" : "output: " + text;
  }

 private:
  std::string program_, serial_, log_;
  std::vector<std::string> extra_;
  pid_t pid_ = -1;
};

// Whether Aravis can reach `camera_id` at all. Not through arv_update_device_list(): that would
// fill Aravis's device list in this process, which AravisCamera must do itself.
bool aravis_reaches(const std::string& camera_id) {
  ArvDevice* device = arv_open_device(camera_id.c_str(), nullptr);
  if (!device) return false;
  g_object_unref(device);
  return true;
}

// The fake camera's diagonal ramp (Mono8), pixel by pixel; returns the first mismatch, or "".
std::string check_ramp8(const Image& img, std::uint32_t frame_id, double scale) {
  for (int y = 0; y < img.format().height; ++y)
    for (int x = 0; x < img.format().width; ++x) {
      const double v =
          std::clamp(static_cast<double>((static_cast<std::uint64_t>(x) + y + frame_id) % 255) * scale, 0.0, 255.0);
      const int want = static_cast<int>(v);
      const int got = img.row(y)[x];
      if (got != want)
        return "frame " + std::to_string(frame_id) + " pixel (" + std::to_string(x) + ", " + std::to_string(y) +
               ") = " + std::to_string(got) + ", the fake camera's ramp gives " + std::to_string(want);
    }
  return "";
}

std::string check_ramp16(const Image& img, std::uint32_t frame_id, double scale) {
  for (int y = 0; y < img.format().height; ++y) {
    const auto* row = reinterpret_cast<const std::uint16_t*>(img.row(y));
    for (int x = 0; x < img.format().width; ++x) {
      const std::uint64_t ramp =
          (256 * static_cast<std::uint64_t>(x) + 256 * std::uint64_t{frame_id} + 256 * static_cast<std::uint64_t>(y)) %
          65535;
      const int want = static_cast<int>(std::clamp(static_cast<double>(ramp) * scale, 0.0, 65535.0));
      if (row[x] != want)
        return "frame " + std::to_string(frame_id) + " pixel (" + std::to_string(x) + ", " + std::to_string(y) +
               ") = " + std::to_string(row[x]) + ", the fake camera's ramp gives " + std::to_string(want);
    }
  }
  return "";
}

// The next GigE Vision 1.x block id: 16 bit, 0 is skipped.
std::uint32_t next_block_id(std::uint32_t id) { return id >= 0xFFFF ? 1 : id + 1; }

class AravisFakeCamera : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto program = find_in_path(kFakeCameraProgram);
    if (!program) GTEST_SKIP() << kFakeCameraProgram << " not found in PATH (Debian package aravis-tools)";
    GvcpProbe probe;
    if (const auto other = probe.discover(std::chrono::milliseconds(300)))
      GTEST_SKIP() << "another GigE Vision device (serial '" << *other
                   << "') already answers on 127.0.0.1:3956; the fake camera needs the port to itself";
    program_ = *program;
    serial_ = "MFC" + std::to_string(::getpid() % 100000) + "T" + std::to_string(counter_++);  // < 16 characters
    camera_id_ = "Aravis-Fake-" + serial_;
    fake_ = std::make_unique<FakeCameraProcess>(program_, serial_, fake_arguments());
    if (const std::string why = fake_->start(); !why.empty())
      GTEST_SKIP() << "the GigE Vision simulator cannot run on loopback here: " << why;
    if (!aravis_reaches(camera_id_))
      GTEST_SKIP() << "Aravis's GigE Vision discovery does not find " << camera_id_
                   << " on loopback here (the fake camera answers a unicast GVCP discovery)";
  }
  void TearDown() override { fake_.reset(); }

  virtual std::vector<std::string> fake_arguments() const { return {}; }

  AravisCameraConfig config(int bits = 8) const {
    AravisCameraConfig c;
    c.camera_id = camera_id_;
    c.width = kWidth;
    c.height = kHeight;
    c.bits_per_pixel = bits;
    c.exposure_us = 10000;  // scale 1 + 0 + log10(1) = 1: the ramp as it is
    c.gain = 0;
    c.frame_timeout = std::chrono::milliseconds(2000);
    return c;
  }

  std::string program_, serial_, camera_id_;
  std::unique_ptr<FakeCameraProcess> fake_;
  static inline int counter_ = 0;
};

TEST(GevFrameIds, GapsCountedAcrossThe16BitWrapWhichSkipsZero) {
  EXPECT_EQ(gev_frames_missed_between(5, 6), 0u);
  EXPECT_EQ(gev_frames_missed_between(5, 9), 3u);
  EXPECT_EQ(gev_frames_missed_between(65535, 1), 0u);      // the wrap skips 0: no frame missed
  EXPECT_EQ(gev_frames_missed_between(65534, 2), 2u);      // 65535 and 1 missed
  EXPECT_EQ(gev_frames_missed_between(7, 7), 0u);          // repeat: restart, not a gap
  EXPECT_EQ(gev_frames_missed_between(500, 3), 0u);        // step back: the camera restarted
  EXPECT_EQ(gev_frames_missed_between(65535, 65536), 0u);  // 64-bit ids (GigE Vision 2, USB3 Vision)
  EXPECT_EQ(gev_frames_missed_between(70000, 70010), 9u);
}

TEST(AravisCameraErrors, UnknownCameraIdIsMissingAndNamed) {
  AravisCameraConfig c;
  c.camera_id = "Aravis-Fake-MFCNOPE" + std::to_string(::getpid());
  AravisCamera camera(c);
  const HalError e = catch_hal([&] { camera.configure(); });
  EXPECT_EQ(e.code(), ErrorCode::DeviceMissing) << e.what();
  EXPECT_TRUE(mentions(e, c.camera_id)) << e.what();
  EXPECT_TRUE(mentions(e, "check")) << e.what();
}

TEST(AravisCameraErrors, LifecycleMisuseNamesTheCamera) {
  AravisCameraConfig c;
  c.camera_id = "Aravis-Fake-MFCLIFE";
  AravisCamera camera(c);
  HalError e = catch_hal([&] { camera.activate(); });
  EXPECT_EQ(e.code(), ErrorCode::InvalidState);
  EXPECT_TRUE(mentions(e, "Aravis-Fake-MFCLIFE")) << e.what();
  Image img(ImageFormat{8, 8, 8});
  FrameInfo info;
  e = catch_hal([&] { camera.read(img, info); });
  EXPECT_EQ(e.code(), ErrorCode::InvalidState);
  e = catch_hal([&] { camera.select_led(0); });  // no strobe configured
  EXPECT_EQ(e.code(), ErrorCode::InvalidState);
}

TEST_F(AravisFakeCamera, CapturesFrameSetsOneSoftwareTriggerPerFlash) {
  AravisCamera camera(config());
  SimulatedLightRing lights;
  MfcSequencer sequencer(camera, lights);
  sequencer.configure();
  EXPECT_EQ(camera.pixel_format_name(), "Mono8");
  ASSERT_EQ(camera.format(), (ImageFormat{kWidth, kHeight, 8}));
  ASSERT_TRUE(camera.applied_exposure_us().has_value());
  EXPECT_DOUBLE_EQ(*camera.applied_exposure_us(), 10000.0);
  EXPECT_TRUE(mentions(HalError(ErrorCode::Io, camera.describe()), camera_id_)) << camera.describe();
  sequencer.activate();

  const auto t0 = Clock::now();
  const FrameSet& set = sequencer.read();
  const double first_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  ASSERT_EQ(set.frames.size(), 9u);
  for (int k = 0; k < FrameSet::kSlots; ++k) {
    const SlotFrame& f = set.frames[static_cast<std::size_t>(k)];
    ASSERT_EQ(f.image.format(), (ImageFormat{kWidth, kHeight, 8})) << "slot " << k;
    EXPECT_EQ(check_ramp8(f.image, f.info.sequence, 1.0), "") << "slot " << k;
    // Stamped just before its trigger, which the sequencer sends after switching the LED.
    EXPECT_GE(f.info.timestamp_ns, f.on_ns) << "slot " << k;
    EXPECT_LE(f.info.timestamp_ns, f.off_ns) << "slot " << k;
    EXPECT_EQ(f.stale_discarded, 0) << "slot " << k;
    if (k > 0) {  // one frame per trigger: consecutive ids, so the images differ
      const SlotFrame& prev = set.frames[static_cast<std::size_t>(k - 1)];
      EXPECT_EQ(f.info.sequence, next_block_id(prev.info.sequence)) << "slot " << k;
      EXPECT_NE(std::memcmp(f.image.data(), prev.image.data(), f.image.size_bytes()), 0) << "slot " << k;
    }
  }
  EXPECT_EQ(camera.stats().frames, 9u);
  EXPECT_EQ(camera.stats().timeouts, 0u);
  EXPECT_EQ(camera.stats().error_buffers, 0u);

  // Steady state: no allocation per frame set, across the fake camera's 16-bit frame id wrap
  // (it starts at 65400).
  constexpr int kSets = 16;
  std::uint32_t last = set.frames.back().info.sequence;
  bool wrapped = false;
  const std::uint64_t before = test::allocation_count();
  const std::clock_t cpu0 = std::clock();
  const auto t1 = Clock::now();
  for (int i = 0; i < kSets; ++i) {
    const FrameSet& s = sequencer.read();
    for (const SlotFrame& f : s.frames) {
      wrapped = wrapped || f.info.sequence < last;
      last = f.info.sequence;
    }
  }
  const double per_set_ms = std::chrono::duration<double, std::milli>(Clock::now() - t1).count() / kSets;
  const double cpu_per_set_ms = 1000.0 * static_cast<double>(std::clock() - cpu0) / CLOCKS_PER_SEC / kSets;
  const std::uint64_t allocations = test::allocation_count() - before;
  EXPECT_EQ(allocations, 0u) << "allocations over " << kSets << " frame sets";
  EXPECT_TRUE(wrapped) << "the frame ids never wrapped (last " << last << ")";
  EXPECT_EQ(camera.stats().dropped_frames, 0u);
  EXPECT_EQ(camera.stats().frames, 9u * (kSets + 1));
  const SlotFrame& after = sequencer.read().frames[4];
  EXPECT_EQ(check_ramp8(after.image, after.info.sequence, 1.0), "");
  std::cout << "[ figures  ] first frame set " << first_ms << " ms, steady state " << per_set_ms << " ms per set of 9 ("
            << cpu_per_set_ms << " ms process CPU; " << kWidth << "x" << kHeight
            << " Mono8, fake camera on loopback, which answers triggers on 40 ms ticks)\n";
  RecordProperty("frame_set_ms", std::to_string(per_set_ms));
  sequencer.deactivate();
}

TEST_F(AravisFakeCamera, Mono16FramesKeepAllSixteenBits) {
  AravisCamera camera(config(16));
  camera.configure();
  EXPECT_EQ(camera.pixel_format_name(), "Mono16");
  EXPECT_EQ(camera.source_format(), SourceFormat::Y16);
  ASSERT_EQ(camera.format(), (ImageFormat{kWidth, kHeight, 16}));
  camera.activate();
  Image img(camera.format());
  FrameInfo info;
  for (int i = 0; i < 3; ++i) {
    camera.read(img, info);
    EXPECT_EQ(check_ramp16(img, info.sequence, 1.0), "");
  }
  camera.deactivate();
}

TEST_F(AravisFakeCamera, OpensByIpAddressToo) {
  AravisCameraConfig c = config();
  c.camera_id = "127.0.0.1";  // located by a unicast discovery
  AravisCamera camera(c);
  camera.configure();
  EXPECT_EQ(camera.describe(), "Aravis 127.0.0.1 (Aravis Fake)");
  camera.activate();
  Image img(camera.format());
  FrameInfo info;
  camera.read(img, info);
  EXPECT_EQ(check_ramp8(img, info.sequence, 1.0), "");
}

TEST_F(AravisFakeCamera, ManualExposureAndGainReachTheSensor) {
  AravisCameraConfig c = config();
  c.exposure_us = 100000;  // log10(100000 / 10000) = 1
  c.gain = 1;              // scale 1 + 1 + 1 = 3
  {
    AravisCamera camera(c);
    camera.configure();
    ASSERT_TRUE(camera.applied_exposure_us() && camera.applied_gain());
    EXPECT_DOUBLE_EQ(*camera.applied_exposure_us(), 100000.0);
    EXPECT_DOUBLE_EQ(*camera.applied_gain(), 1.0);
    camera.activate();
    Image img(camera.format());
    FrameInfo info;
    camera.read(img, info);
    EXPECT_EQ(check_ramp8(img, info.sequence, 3.0), "");
    EXPECT_NE(check_ramp8(img, info.sequence, 1.0), "");  // the scaling is visible
  }                                                       // gives up control of the camera

  c.exposure_us = 5;  // the fake camera's range starts at 10 us
  AravisCamera refused(c);
  const HalError e = catch_hal([&] { refused.configure(); });
  EXPECT_EQ(e.code(), ErrorCode::Io);
  EXPECT_TRUE(mentions(e, camera_id_) && mentions(e, "exposure") && mentions(e, "range")) << e.what();
}

TEST_F(AravisFakeCamera, LifecycleIsEnforcedOnARealConnection) {
  AravisCamera camera(config());
  camera.configure();
  Image img(camera.format());
  FrameInfo info;
  EXPECT_EQ(catch_hal([&] { camera.read(img, info); }).code(), ErrorCode::InvalidState);
  camera.activate();
  EXPECT_EQ(catch_hal([&] { camera.configure(); }).code(), ErrorCode::InvalidState);
  Image wrong(ImageFormat{kWidth, kHeight, 16});
  EXPECT_EQ(catch_hal([&] { camera.read(wrong, info); }).code(), ErrorCode::InvalidState);
  camera.read(img, info);
  EXPECT_EQ(check_ramp8(img, info.sequence, 1.0), "");
  camera.deactivate();
  camera.configure();  // reconfigure after deactivate: a fresh connection
  camera.activate();
  camera.read(img, info);
  EXPECT_EQ(check_ramp8(img, info.sequence, 1.0), "");
}

TEST_F(AravisFakeCamera, SecondControllerIsRefusedNamingTheCause) {
  AravisCamera first(config());
  first.configure();
  AravisCamera second(config());
  const HalError e = catch_hal([&] { second.configure(); });
  EXPECT_EQ(e.code(), ErrorCode::Io) << e.what();
  EXPECT_TRUE(mentions(e, camera_id_) && mentions(e, "controls the camera")) << e.what();
  // The first one keeps control and keeps delivering. A frame lost on loopback under load (a
  // starved stream thread) is a stream timeout the camera recovers from on its next read, as on a
  // real link; losing control, or a second timeout in a row, fails the test.
  first.activate();
  Image img(first.format());
  FrameInfo info;
  try {
    first.read(img, info);
  } catch (const HalError& lost) {
    ASSERT_EQ(lost.code(), ErrorCode::StreamTimeout) << lost.what();
    const CameraStats& s = first.stats();
    std::cerr << "first read lost its frame (" << lost.what() << "); error buffers " << s.error_buffers << ", timeouts "
              << s.timeouts << "; the fake camera's " << fake_->output() << "\n";
    first.read(img, info);
  }
  EXPECT_EQ(check_ramp8(img, info.sequence, 1.0), "");
}

TEST_F(AravisFakeCamera, AbsurdlyShortTimeoutIsAStreamTimeoutNamingTheCamera) {
  AravisCameraConfig c = config();
  c.frame_timeout = std::chrono::milliseconds(1);  // the fake camera answers a trigger on its next 40 ms tick
  AravisCamera camera(c);
  camera.configure();
  camera.activate();
  Image img(camera.format());
  FrameInfo info;
  std::optional<HalError> timeout;
  for (int i = 0; i < 20 && !timeout; ++i) {
    try {
      camera.read(img, info);
    } catch (const HalError& e) {
      timeout = e;
    }
  }
  ASSERT_TRUE(timeout) << "20 frames within 1 ms of their trigger";
  EXPECT_EQ(timeout->code(), ErrorCode::StreamTimeout) << timeout->what();
  EXPECT_TRUE(mentions(*timeout, camera_id_) && mentions(*timeout, "1 ms")) << timeout->what();
  EXPECT_GE(camera.stats().timeouts, 1u);
  // The acquisition restarts and the next trigger's own frame arrives.
  camera.set_frame_timeout(std::chrono::milliseconds(2000));
  const std::uint64_t frames = camera.stats().frames;
  camera.read(img, info);
  EXPECT_EQ(check_ramp8(img, info.sequence, 1.0), "");
  EXPECT_EQ(camera.stats().frames, frames + 1);
}

class AravisFakeCameraLosingEveryPacket : public AravisFakeCamera {
  std::vector<std::string> fake_arguments() const override { return {"-r", "1000"}; }  // GVSP lost per thousand
};

TEST_F(AravisFakeCameraLosingEveryPacket, NoFrameIsAStreamTimeoutAfterTheFrameTimeout) {
  AravisCameraConfig c = config();
  c.frame_timeout = std::chrono::milliseconds(300);
  AravisCamera camera(c);
  camera.configure();  // control works: only the stream's packets are lost
  camera.activate();
  Image img(camera.format());
  FrameInfo info;
  for (int attempt = 0; attempt < 2; ++attempt) {  // the second one after the acquisition restart
    const auto t0 = Clock::now();
    const HalError e = catch_hal([&] { camera.read(img, info); });
    const auto waited = std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - t0);
    EXPECT_EQ(e.code(), ErrorCode::StreamTimeout) << e.what();
    EXPECT_TRUE(mentions(e, camera_id_) && mentions(e, "300 ms") && mentions(e, "check")) << e.what();
    EXPECT_GE(waited.count(), 300);
    EXPECT_LT(waited.count(), 3000);
  }
  EXPECT_EQ(camera.stats().timeouts, 2u);
  EXPECT_EQ(camera.stats().frames, 0u);
  // Silent across restarts: the third timeout in a row reopens the camera, as a lost stream
  // channel needs a new connection; the next read reconnects after the backoff.
  static_assert(AravisCamera::kSilentTriggersBeforeReopen == 3);
  const HalError lost = catch_hal([&] { camera.read(img, info); });
  EXPECT_EQ(lost.code(), ErrorCode::DeviceGone) << lost.what();
  EXPECT_TRUE(mentions(lost, camera_id_) && mentions(lost, "3 software triggers") && mentions(lost, "reopening"))
      << lost.what();
  EXPECT_EQ(camera.stats().timeouts, 3u);
}

TEST_F(AravisFakeCamera, CameraVanishingIsDeviceGoneThenItReconnects) {
  AravisCamera camera(config());
  camera.configure();
  camera.activate();
  Image img(camera.format());
  FrameInfo info;
  camera.read(img, info);
  ASSERT_EQ(check_ramp8(img, info.sequence, 1.0), "");

  fake_->kill();
  const auto t0 = Clock::now();
  const HalError gone = catch_hal([&] { camera.read(img, info); });
  const double detect_s = std::chrono::duration<double>(Clock::now() - t0).count();
  EXPECT_EQ(gone.code(), ErrorCode::DeviceGone) << gone.what();
  EXPECT_TRUE(mentions(gone, camera_id_) && mentions(gone, "reconnecting")) << gone.what();
  // Our GVCP command's retries (Aravis 0.8: 5 x 500 ms), at worst after those of a heartbeat read
  // holding the control channel; the ~10 s teardown runs in the background, not in read().
  EXPECT_LT(detect_s, 8.0);
  // While it is away every read() says so, naming it (a reconnect attempt at most per backoff).
  const HalError still = catch_hal([&] { camera.read(img, info); });
  EXPECT_EQ(still.code(), ErrorCode::DeviceGone) << still.what();
  EXPECT_TRUE(mentions(still, camera_id_)) << still.what();

  ASSERT_EQ(fake_->start(), "");  // the same camera (serial, id) comes back
  const auto t1 = Clock::now();
  bool captured = false;
  int failures = 0;
  while (!captured && Clock::now() - t1 < std::chrono::seconds(30)) {
    try {
      camera.read(img, info);
      captured = true;
    } catch (const HalError& e) {
      ++failures;
      // Gone until reopened; a reopened connection whose stream stays silent times out until the
      // camera is reopened again (kSilentTriggersBeforeReopen).
      EXPECT_TRUE(e.code() == ErrorCode::DeviceGone || e.code() == ErrorCode::StreamTimeout) << e.what();
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  }
  const double reconnect_s = std::chrono::duration<double>(Clock::now() - t1).count();
  ASSERT_TRUE(captured) << "no frame within 30 s of the camera's return";
  EXPECT_EQ(check_ramp8(img, info.sequence, 1.0), "");
  EXPECT_GE(camera.stats().reconnects, 1u);
  camera.read(img, info);  // and it goes on
  EXPECT_EQ(check_ramp8(img, info.sequence, 1.0), "");
  std::cout << "[ figures  ] camera gone detected after " << detect_s << " s; frame again " << reconnect_s
            << " s after the camera was back (" << failures << " DeviceGone reads meanwhile)\n";
}

TEST_F(AravisFakeCamera, StrobeOutputsNeedLineFeaturesTheFakeCameraLacks) {
  AravisCameraConfig c = config();
  c.strobe = CameraStrobeConfig{};
  AravisCamera camera(c);
  AravisStrobeLightRing lights(camera);
  MfcSequencer sequencer(camera, lights);
  const HalError e = catch_hal([&] { sequencer.configure(); });
  EXPECT_EQ(e.code(), ErrorCode::MissingFeature) << e.what();
  EXPECT_TRUE(mentions(e, "'LineSelector'") && mentions(e, camera_id_) && mentions(e, "gpiod")) << e.what();
  EXPECT_EQ(catch_hal([&] { sequencer.activate(); }).code(), ErrorCode::InvalidState);
}

// Digital I/O for the fake camera: SFNC features (LineSelector, LineMode, LineSource, LineInverter,
// UserOutputSelector/Value, TimerSelector/TriggerSource/Duration) added to its own GenICam file, on
// registers of its 64 KiB register space that it does not use (plain memory: what a host writes
// there is what a GVCP read returns). Register map, 4 bytes per line / output (pIndex):
constexpr std::uint32_t kLineModeReg = 0x8100, kLineSourceReg = 0x8200, kLineInverterReg = 0x8300,
                        kUserOutputValueReg = 0x8500, kTimerDurationReg = 0x8600, kTimerTriggerSourceReg = 0x8608;
enum LineSourceValue : std::uint32_t { kOff = 0, kExposureActive = 1, kUserOutput0 = 2, kTimer0Active = 5 };

const char* const kIoFeatures = R"xml(
  <Enumeration Name="LineSelector" NameSpace="Standard">
    <EnumEntry Name="Line0" NameSpace="Standard"><Value>0</Value></EnumEntry>
    <EnumEntry Name="Line1" NameSpace="Standard"><Value>1</Value></EnumEntry>
    <EnumEntry Name="Line2" NameSpace="Standard"><Value>2</Value></EnumEntry>
    <EnumEntry Name="Line3" NameSpace="Standard"><Value>3</Value></EnumEntry>
    <EnumEntry Name="Line4" NameSpace="Standard"><Value>4</Value></EnumEntry>
    <pValue>MfcLineSelectorReg</pValue>
  </Enumeration>
  <IntReg Name="MfcLineSelectorReg" NameSpace="Custom">
    <Address>0x8000</Address><Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>BigEndian</Endianess>
  </IntReg>
  <Enumeration Name="LineMode" NameSpace="Standard">
    <EnumEntry Name="Input" NameSpace="Standard"><Value>0</Value></EnumEntry>
    <EnumEntry Name="Output" NameSpace="Standard"><Value>1</Value></EnumEntry>
    <pValue>MfcLineModeReg</pValue>
  </Enumeration>
  <IntReg Name="MfcLineModeReg" NameSpace="Custom">
    <Address>0x8100</Address><pIndex Offset="4">LineSelector</pIndex><Length>4</Length><AccessMode>RW</AccessMode>
    <pPort>Device</pPort><Sign>Unsigned</Sign><Endianess>BigEndian</Endianess>
  </IntReg>
  <Enumeration Name="LineSource" NameSpace="Standard">
    <EnumEntry Name="Off" NameSpace="Standard"><Value>0</Value></EnumEntry>
    <EnumEntry Name="ExposureActive" NameSpace="Standard"><Value>1</Value></EnumEntry>
    <EnumEntry Name="UserOutput0" NameSpace="Standard"><Value>2</Value></EnumEntry>
    <EnumEntry Name="UserOutput1" NameSpace="Standard"><Value>3</Value></EnumEntry>
    <EnumEntry Name="UserOutput2" NameSpace="Standard"><Value>4</Value></EnumEntry>
    <EnumEntry Name="Timer0Active" NameSpace="Standard"><Value>5</Value></EnumEntry>
    <pValue>MfcLineSourceReg</pValue>
  </Enumeration>
  <IntReg Name="MfcLineSourceReg" NameSpace="Custom">
    <Address>0x8200</Address><pIndex Offset="4">LineSelector</pIndex><Length>4</Length><AccessMode>RW</AccessMode>
    <pPort>Device</pPort><Sign>Unsigned</Sign><Endianess>BigEndian</Endianess>
  </IntReg>
  <Boolean Name="LineInverter" NameSpace="Standard">
    <pValue>MfcLineInverterReg</pValue><OnValue>1</OnValue><OffValue>0</OffValue>
  </Boolean>
  <IntReg Name="MfcLineInverterReg" NameSpace="Custom">
    <Address>0x8300</Address><pIndex Offset="4">LineSelector</pIndex><Length>4</Length><AccessMode>RW</AccessMode>
    <pPort>Device</pPort><Sign>Unsigned</Sign><Endianess>BigEndian</Endianess>
  </IntReg>
  <Enumeration Name="UserOutputSelector" NameSpace="Standard">
    <EnumEntry Name="UserOutput0" NameSpace="Standard"><Value>0</Value></EnumEntry>
    <EnumEntry Name="UserOutput1" NameSpace="Standard"><Value>1</Value></EnumEntry>
    <EnumEntry Name="UserOutput2" NameSpace="Standard"><Value>2</Value></EnumEntry>
    <pValue>MfcUserOutputSelectorReg</pValue>
  </Enumeration>
  <IntReg Name="MfcUserOutputSelectorReg" NameSpace="Custom">
    <Address>0x8400</Address><Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>BigEndian</Endianess>
  </IntReg>
  <Boolean Name="UserOutputValue" NameSpace="Standard">
    <pValue>MfcUserOutputValueReg</pValue><OnValue>1</OnValue><OffValue>0</OffValue>
  </Boolean>
  <IntReg Name="MfcUserOutputValueReg" NameSpace="Custom">
    <Address>0x8500</Address><pIndex Offset="4">UserOutputSelector</pIndex><Length>4</Length><AccessMode>RW</AccessMode>
    <pPort>Device</pPort><Sign>Unsigned</Sign><Endianess>BigEndian</Endianess>
  </IntReg>
  <Enumeration Name="TimerSelector" NameSpace="Standard">
    <EnumEntry Name="Timer0" NameSpace="Standard"><Value>0</Value></EnumEntry>
    <pValue>MfcTimerSelectorReg</pValue>
  </Enumeration>
  <IntReg Name="MfcTimerSelectorReg" NameSpace="Custom">
    <Address>0x8604</Address><Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>BigEndian</Endianess>
  </IntReg>
  <Enumeration Name="TimerTriggerSource" NameSpace="Standard">
    <EnumEntry Name="Off" NameSpace="Standard"><Value>0</Value></EnumEntry>
    <EnumEntry Name="ExposureStart" NameSpace="Standard"><Value>1</Value></EnumEntry>
    <pValue>MfcTimerTriggerSourceReg</pValue>
  </Enumeration>
  <IntReg Name="MfcTimerTriggerSourceReg" NameSpace="Custom">
    <Address>0x8608</Address><Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>BigEndian</Endianess>
  </IntReg>
  <Float Name="TimerDuration" NameSpace="Standard">
    <pValue>MfcTimerDurationConverter</pValue><Min>0</Min><Max>1000000</Max>
  </Float>
  <Converter Name="MfcTimerDurationConverter" NameSpace="Custom">
    <FormulaTo>FROM</FormulaTo><FormulaFrom>TO</FormulaFrom><pValue>MfcTimerDurationReg</pValue>
  </Converter>
  <IntReg Name="MfcTimerDurationReg" NameSpace="Custom">
    <Address>0x8600</Address><Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>BigEndian</Endianess>
  </IntReg>
)xml";

// A LightRing that reads the camera's line registers back after every set(), over its own GVCP
// socket: what the LED driver would see on the strobe and select lines at that moment.
class ProbedRing final : public LightRing {
 public:
  struct Seen {
    LedMask mask;
    std::uint32_t strobe_source;  // LineSource of Line1
    int index;                    // UserOutput0..2 as bits 0..2
  };
  ProbedRing(LightRing& ring, GvcpProbe& probe) : ring_(ring), probe_(probe) {}
  void configure() override { ring_.configure(); }
  void activate() override { ring_.activate(); }
  void deactivate() override { ring_.deactivate(); }
  void set(LedMask mask) override {
    ring_.set(mask);
    int index = 0;
    for (std::uint32_t k = 0; k < 3; ++k)
      index |= static_cast<int>(probe_.read_register(kUserOutputValueReg + 4 * k).value_or(9) & 1) << k;
    seen.push_back({mask, probe_.read_register(kLineSourceReg + 4).value_or(99), index});
  }
  LedMask state() const override { return ring_.state(); }
  std::string describe() const override { return ring_.describe(); }
  std::vector<Seen> seen;

 private:
  LightRing& ring_;
  GvcpProbe& probe_;
};

class AravisFakeCameraWithOutputs : public AravisFakeCamera {
 protected:
  // Restarts the fake camera (same serial) on its own GenICam file plus the I/O features above.
  void SetUp() override {
    AravisFakeCamera::SetUp();
    if (IsSkipped()) return;
    std::string xml;
    {
      GError* error = nullptr;
      ArvCamera* cam = arv_camera_new(camera_id_.c_str(), &error);
      ASSERT_NE(cam, nullptr) << (error ? error->message : "");
      std::size_t size = 0;
      const char* data = arv_device_get_genicam_xml(arv_camera_get_device(cam), &size);
      ASSERT_NE(data, nullptr);
      xml.assign(data, size);
      g_object_unref(cam);
    }
    const std::size_t end = xml.rfind("</RegisterDescription>");
    ASSERT_NE(end, std::string::npos) << "the fake camera's GenICam file has no </RegisterDescription>";
    xml.insert(end, kIoFeatures);
    genicam_ = "/tmp/mfcd-arv-fake-" + serial_ + ".xml";
    std::ofstream(genicam_) << xml;
    fake_ = std::make_unique<FakeCameraProcess>(program_, serial_, std::vector<std::string>{"-g", genicam_});
    ASSERT_EQ(fake_->start(), "");
  }
  void TearDown() override {
    AravisFakeCamera::TearDown();
    if (!genicam_.empty()) std::remove(genicam_.c_str());
  }
  std::string genicam_;
};

TEST_F(AravisFakeCameraWithOutputs, StrobeAndSelectLinesFollowEveryFlashOfAFrameSet) {
  AravisCameraConfig c = config();
  c.strobe = CameraStrobeConfig{};  // strobe Line1 (ExposureActive), select Line2..Line4
  c.strobe->strobe_inverted = true;
  AravisCamera camera(c);
  AravisStrobeLightRing strobe(camera);
  GvcpProbe probe;
  ProbedRing lights(strobe, probe);
  MfcSequencer sequencer(camera, lights);
  sequencer.configure();
  for (std::uint32_t line = 1; line <= 4; ++line)
    EXPECT_EQ(probe.read_register(kLineModeReg + 4 * line), 1u) << "Line" << line << " is an output";
  EXPECT_EQ(probe.read_register(kLineModeReg), 0u) << "Line0 (not configured) left alone";
  EXPECT_EQ(probe.read_register(kLineSourceReg + 4), kOff) << "strobe dark after configure";
  for (std::uint32_t k = 0; k < 3; ++k)
    EXPECT_EQ(probe.read_register(kLineSourceReg + 4 * (2 + k)), kUserOutput0 + k) << "select line Line" << 2 + k;
  EXPECT_EQ(probe.read_register(kLineInverterReg + 4), 1u) << "strobe line inverted";
  EXPECT_EQ(probe.read_register(kLineInverterReg + 8), 0u);

  sequencer.activate();
  const FrameSet& set = sequencer.read();
  for (const SlotFrame& f : set.frames) EXPECT_EQ(check_ramp8(f.image, f.info.sequence, 1.0), "");
  ASSERT_EQ(lights.seen.size(), 16u);  // on, off per LED
  for (int led = 0; led < kLedCount; ++led) {
    const ProbedRing::Seen& on = lights.seen[static_cast<std::size_t>(2 * led)];
    const ProbedRing::Seen& off = lights.seen[static_cast<std::size_t>(2 * led + 1)];
    EXPECT_EQ(on.mask, 1u << led);
    EXPECT_EQ(on.index, led) << "select lines carry the LED index";
    EXPECT_EQ(on.strobe_source, kExposureActive) << "LED " << led;
    EXPECT_EQ(off.mask, 0u);
    EXPECT_EQ(off.strobe_source, kOff) << "dark after LED " << led;
  }
  EXPECT_EQ(strobe.state(), 0u);
  // The strobe writes allocate nothing either (the probe's record is reserved beforehand).
  lights.seen.clear();
  lights.seen.reserve(64);
  const std::uint64_t before = test::allocation_count();
  sequencer.read();
  EXPECT_EQ(test::allocation_count() - before, 0u) << "allocations over a frame set with the camera strobe";
  EXPECT_EQ(lights.seen.size(), 16u);
  EXPECT_EQ(catch_hal([&] { strobe.set(0x03); }).code(), ErrorCode::InvalidState);  // one index at a time
  sequencer.deactivate();
  EXPECT_EQ(probe.read_register(kLineSourceReg + 4), kOff);
}

TEST_F(AravisFakeCameraWithOutputs, TimerStrobeAndWrongLinesAreConfiguredOrRefused) {
  AravisCameraConfig c = config();
  c.strobe = CameraStrobeConfig{};
  c.strobe->source = StrobeSource::Timer;
  c.strobe->pulse_us = 1500;
  {
    AravisCamera camera(c);
    camera.configure();
    GvcpProbe probe;
    EXPECT_EQ(probe.read_register(kTimerTriggerSourceReg), 1u) << "TimerTriggerSource = ExposureStart";
    EXPECT_EQ(probe.read_register(kTimerDurationReg), 1500u) << "TimerDuration (us)";
    camera.select_led(6);
    EXPECT_EQ(probe.read_register(kLineSourceReg + 4), kTimer0Active);
    EXPECT_EQ(probe.read_register(kUserOutputValueReg), 0u);
    EXPECT_EQ(probe.read_register(kUserOutputValueReg + 4), 1u);
    EXPECT_EQ(probe.read_register(kUserOutputValueReg + 8), 1u);
    camera.select_led(AravisCamera::kNoLed);
    EXPECT_EQ(probe.read_register(kLineSourceReg + 4), kOff);
  }
  c.strobe->source = StrobeSource::ExposureActive;
  c.strobe->select_lines[2] = "Line7";
  AravisCamera wrong(c);
  HalError e = catch_hal([&] { wrong.configure(); });
  EXPECT_EQ(e.code(), ErrorCode::WrongLine) << e.what();
  EXPECT_TRUE(mentions(e, "'Line7'") && mentions(e, "Line0, Line1, Line2, Line3, Line4") && mentions(e, camera_id_))
      << e.what();
  c.strobe->select_lines[2] = "Line1";  // the strobe line twice
  AravisCamera twice(c);
  e = catch_hal([&] { twice.configure(); });
  EXPECT_EQ(e.code(), ErrorCode::WrongLine) << e.what();
  EXPECT_TRUE(mentions(e, "twice")) << e.what();
}

}  // namespace
}  // namespace mfcd::hal
