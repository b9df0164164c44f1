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

#include "base/unique_fd.hpp"
#include "mfcd/hal/camera.hpp"

namespace mfcd::hal {

struct V4L2CameraConfig {
  std::string device = "/dev/video0";
  int width = 640;
  int height = 480;
  int bits_per_pixel = 8;          // output depth: 8 or 16
  int frame_rate = 0;              // frames per second to ask for (VIDIOC_S_PARM); 0 = device default
  std::optional<int> exposure_us;  // manual exposure, if the device has the control
  std::optional<int> gain;         // manual gain, if the device has the control
  int buffer_count = 4;
  std::chrono::milliseconds dequeue_timeout{1000};
  std::chrono::milliseconds reconnect_backoff_min{100};
  std::chrono::milliseconds reconnect_backoff_max{5000};
};

// Pixel formats the camera can convert (fourcc values from videodev2.h).
enum class SourceFormat { Grey, Y16, Yuyv };

// Conversion of one frame into grey; exposed for the reference tests.
void convert_to_grey(SourceFormat source, const std::uint8_t* src, std::size_t src_stride, Image& out);

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
  std::int64_t exposure_lead_ns() const override { return exposure_lead_ns_; }
  const CameraStats& stats() const override { return stats_; }
  std::string describe() const override;

  SourceFormat source_format() const { return source_; }
  const std::string& driver() const { return driver_; }
  bool exposure_applied() const { return exposure_applied_; }
  bool gain_applied() const { return gain_applied_; }

 private:
  static constexpr int kMaxBuffers = 16;
  struct Mapping {
    void* data = nullptr;
    std::size_t length = 0;
  };
  void open();
  void negotiate();
  void apply_controls();
  void allocate_buffers();
  void release_buffers();
  void close() noexcept;
  void stream_on();
  void stream_off() noexcept;
  void try_reconnect();
  [[noreturn]] void fail(int err, const char* what);

  V4L2CameraConfig config_;
  UniqueFd fd_;
  std::string driver_, card_;
  ImageFormat format_;
  SourceFormat source_ = SourceFormat::Grey;
  std::size_t src_stride_ = 0;
  std::int64_t exposure_lead_ns_ = 0;
  std::array<Mapping, kMaxBuffers> buffers_{};
  int buffer_count_ = 0;
  bool configured_ = false, active_ = false, streaming_ = false;
  bool gone_ = false, restart_stream_ = false;
  bool have_sequence_ = false;
  std::uint32_t last_sequence_ = 0;
  std::int64_t next_reconnect_ns_ = 0;
  std::chrono::milliseconds backoff_{0};
  bool exposure_applied_ = false, gain_applied_ = false;
  CameraStats stats_;
};

}  // namespace mfcd::hal
