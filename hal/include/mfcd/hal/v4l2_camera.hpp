#pragma once
// V4L2Camera: mmap streaming capture from a V4L2 node (REQBUFS/QBUF/STREAMON, non-blocking fd + poll,
// DQBUF), converting GREY / Y16 / YUYV to 8- or 16-bit grey. Handles error buffers (re-queued),
// dropped frames (sequence gaps), a dequeue watchdog (timeout → error, streaming restarted on the next
// read()), and unplug (ENODEV → error, reopened with exponential backoff on later read()s).
#include <array>
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>

#include "mfcd/hal/camera.hpp"

namespace mfcd::hal {

struct V4L2CameraConfig {
  std::string device = "/dev/video0";
  int width = 640;
  int height = 480;
  int bitsPerPixel = 8;           // output depth: 8 or 16
  int frameRate = 0;              // frames per second to ask for (VIDIOC_S_PARM); 0 = device default
  std::optional<int> exposureUs;  // manual exposure, if the device has the control
  std::optional<int> gain;        // manual gain, if the device has the control
  int bufferCount = 4;
  std::chrono::milliseconds dequeueTimeout{1000};
  std::chrono::milliseconds reconnectBackoffMin{100};
  std::chrono::milliseconds reconnectBackoffMax{5000};
};

// Pixel formats the camera can convert (fourcc values from videodev2.h).
enum class SourceFormat { Grey, Y16, Yuyv };

// Conversion of one frame into grey; exposed for the reference tests.
void convertToGrey(SourceFormat source, const std::uint8_t* src, std::size_t srcStride, Image& out);

class V4L2Camera final : public Camera {
 public:
  explicit V4L2Camera(V4L2CameraConfig config);
  ~V4L2Camera() override;
  V4L2Camera(const V4L2Camera&) = delete;
  V4L2Camera& operator=(const V4L2Camera&) = delete;

  void configure() override;
  void activate() override;
  void deactivate() override;
  void read(Image& out, FrameInfo& info) override;
  ImageFormat format() const override { return format_; }
  std::int64_t exposureLeadNs() const override { return exposureLeadNs_; }
  const CameraStats& stats() const override { return stats_; }
  std::string describe() const override;

  SourceFormat sourceFormat() const { return source_; }
  const std::string& driver() const { return driver_; }
  bool exposureApplied() const { return exposureApplied_; }
  bool gainApplied() const { return gainApplied_; }

 private:
  static constexpr int kMaxBuffers = 16;
  struct Mapping {
    void* data = nullptr;
    std::size_t length = 0;
  };
  void open();
  void negotiate();
  void applyControls();
  void allocateBuffers();
  void releaseBuffers();
  void close() noexcept;
  void streamOn();
  void streamOff() noexcept;
  void tryReconnect();
  [[noreturn]] void fail(int err, const char* what);

  V4L2CameraConfig config_;
  int fd_ = -1;
  std::string driver_, card_;
  ImageFormat format_;
  SourceFormat source_ = SourceFormat::Grey;
  std::size_t srcStride_ = 0;
  std::int64_t exposureLeadNs_ = 0;
  std::array<Mapping, kMaxBuffers> buffers_{};
  int bufferCount_ = 0;
  bool configured_ = false, active_ = false, streaming_ = false;
  bool gone_ = false, restartStream_ = false;
  bool haveSequence_ = false;
  std::uint32_t lastSequence_ = 0;
  std::int64_t nextReconnectNs_ = 0;
  std::chrono::milliseconds backoff_{0};
  bool exposureApplied_ = false, gainApplied_ = false;
  CameraStats stats_;
};

}  // namespace mfcd::hal
