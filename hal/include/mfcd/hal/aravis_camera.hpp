#pragma once
// AravisCamera: a GenICam camera (GigE Vision or USB3 Vision) through Aravis 0.8, beside V4L2Camera
// and SimulatedCamera: the same lifecycle, errors naming the device, the same grey images. One
// exposure per read(): the camera runs with TriggerMode=On, TriggerSource=Software on FrameStart,
// and read() sends TriggerSoftware and waits for that frame, so every frame of a FrameSet was
// exposed after its LED was switched. Buffers are allocated and pushed to the Aravis stream once
// at configure(); read() pops one, converts it (convert_to_grey, as V4L2Camera does) and pushes it
// back. Frame timeout → StreamTimeout (the acquisition is restarted on the next read()); the camera
// not answering (GVCP timeout, heartbeat lost) → DeviceGone, the connection released (in the
// background), reopened from later read()s with exponential backoff (100 ms doubling to 5 s), as
// V4L2Camera does on ENODEV.
// Optionally the camera's digital outputs fire the LEDs (CameraStrobeConfig, AravisStrobeLightRing;
// wiring in docs/hal.md).
#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include "mfcd/hal/camera.hpp"
#include "mfcd/hal/light_ring.hpp"   // kLedCount
#include "mfcd/hal/v4l2_camera.hpp"  // SourceFormat, convert_to_grey

namespace mfcd::hal {

// What drives the strobe line while an LED is selected.
enum class StrobeSource {
  ExposureActive,  // LineSource=ExposureActive: the LED is lit exactly while the sensor exposes
  Timer,           // LineSource=Timer<n>Active, the timer started by ExposureStart: a fixed pulse
};

// The LEDs fired by the camera's outputs instead of GPIO lines: the strobe line carries the flash
// pulse to the LED driver's strobe (gate) input, three select lines carry the LED index (bit 0..2)
// to its channel select inputs (a 3-to-8 decoder). Line names are the camera's LineSelector entries.
struct CameraStrobeConfig {
  std::string strobe_line = "Line1";
  std::array<std::string, 3> select_lines{"Line2", "Line3", "Line4"};  // LED index bit 0, 1, 2
  StrobeSource source = StrobeSource::ExposureActive;
  int pulse_us = 0;              // Timer: pulse length in µs from the start of exposure (TimerDuration)
  bool strobe_inverted = false;  // LineInverter on the strobe line: the driver's input is active low
};

struct AravisCameraConfig {
  std::string camera_id;  // Aravis device id ("Basler-21234567", "Aravis-Fake-MFC1"), or an IP address
  int width = 640;
  int height = 480;
  int bits_per_pixel = 8;             // output depth: 8 or 16 (Mono8 / Mono16 from the camera)
  std::optional<double> exposure_us;  // manual exposure in µs (auto exposure off)
  std::optional<double> gain;         // manual gain in the camera's unit (Gain: dB; GainRaw: counts), auto off
  int buffer_count = 4;
  std::chrono::milliseconds frame_timeout{1000};  // software trigger → complete frame
  std::chrono::milliseconds reconnect_backoff_min{100};
  std::chrono::milliseconds reconnect_backoff_max{5000};
  int packet_size = 0;  // GigE Vision stream packet size in bytes (jumbo frames); 0 = Aravis's choice
  std::optional<CameraStrobeConfig> strobe;  // the LEDs are fired by the camera's outputs
};

// Frames a GenICam camera sent but the stream did not deliver, between two delivered frame ids.
// GigE Vision 1.x block ids are 16 bit and skip 0 (..., 65534, 65535, 1, 2, ...); GigE Vision 2 and
// USB3 Vision ids are 64 bit. A repeat or a step back is a restart (a reconnected camera counts from
// its own start), not a gap.
constexpr std::uint64_t gev_frames_missed_between(std::uint64_t previous, std::uint64_t current) {
  std::uint64_t step = 0;
  if (previous >= 1 && previous <= 0xFFFF && current >= 1 && current <= 0xFFFF)
    step = (current + 0xFFFF - previous) % 0xFFFF;  // modulo the 65535 valid 16-bit ids
  else
    step = current - previous;  // modulo 2^64
  const std::uint64_t limit = previous <= 0xFFFF && current <= 0xFFFF ? 0x8000 : (std::uint64_t{1} << 63);
  return step != 0 && step < limit ? step - 1 : 0;
}

class AravisCamera final : public Camera {
 public:
  static constexpr int kNoLed = -1;
  // Triggers in a row without a frame, each after an acquisition restart, after which read()
  // reopens the camera (DeviceGone, then reconnect with backoff): a stream that stays silent
  // across restarts is a lost stream channel (the camera rebooted and forgot its destination, or
  // the stream goes to another NIC's address), which only a new connection sets up again.
  static constexpr int kSilentTriggersBeforeReopen = 3;

  explicit AravisCamera(AravisCameraConfig config);
  ~AravisCamera() override;  // stops, releases; waits for a lost connection's release still running
  AravisCamera(const AravisCamera&) = delete;
  AravisCamera& operator=(const AravisCamera&) = delete;

  void configure() override;
  void activate() override;
  void deactivate() override;
  void read(Image& out, FrameInfo& info) override;
  ImageFormat format() const override { return format_; }
  // Frames are stamped with CLOCK_MONOTONIC just before their software trigger was sent: the
  // exposure cannot start earlier, so the stamp is a start-of-exposure bound and the lead is 0.
  std::int64_t exposure_lead_ns() const override { return 0; }
  const CameraStats& stats() const override { return stats_; }
  std::string describe() const override;  // "Aravis Aravis-Fake-MFC1 (Aravis Fake)"

  // Camera strobe (config.strobe): the LED (0..7) the next exposures light, or kNoLed for none.
  // Refused (InvalidState) without a strobe configuration or before configure(). With the camera
  // gone, selecting no LED succeeds (nothing exposes, so nothing lights).
  void select_led(int led);
  bool has_strobe() const { return config_.strobe.has_value(); }
  int selected_led() const { return selected_led_; }

  // Changes the frame timeout from the next read() on.
  void set_frame_timeout(std::chrono::milliseconds timeout) { config_.frame_timeout = timeout; }

  SourceFormat source_format() const { return source_; }
  const std::string& pixel_format_name() const { return pixel_format_name_; }  // "Mono8", "Mono16"
  // Exposure (µs) and gain as read back from the camera after setting them; unset if not configured.
  std::optional<double> applied_exposure_us() const { return applied_exposure_us_; }
  std::optional<double> applied_gain() const { return applied_gain_; }
  // Complete frames of earlier triggers (a frame that came after its read() had timed out) thrown
  // away before a trigger.
  std::uint64_t discarded_frames() const { return discarded_frames_; }

 private:
  struct Session;  // the open camera: Aravis objects and the feature accessors (aravis_camera.cpp)
  enum class State { Unconfigured, Configured, Active };
  enum class Call { Configure, Activate, Read, SelectLed };

  void require_state(Call call) const;  // the one lifecycle check: throws InvalidState
  // Runs `op` on the open camera; a DeviceGone error from it releases the camera (mark_gone).
  template <typename Op>
  void while_in_use(Op&& op);
  void open_session();
  void close_session() noexcept;
  void start_acquisition();
  void stop_acquisition() noexcept;
  void restart_acquisition();
  void discard_completed_frames();
  void try_reconnect();
  [[noreturn]] void mark_gone(const std::string& cause);
  void join_releaser() noexcept;

  AravisCameraConfig config_;
  std::unique_ptr<Session> session_;
  std::atomic<bool> control_lost_{false};  // set from Aravis's heartbeat thread ("control-lost")
  State state_ = State::Unconfigured;
  bool gone_ = false, restart_ = false, acquiring_ = false;
  std::string model_;  // "<vendor> <model>" once opened, for messages
  ImageFormat format_;
  SourceFormat source_ = SourceFormat::Grey;
  std::string pixel_format_name_;
  std::optional<double> applied_exposure_us_, applied_gain_;
  // Strobe: the feature values written per select_led(), prepared at configure().
  std::string strobe_lit_source_, strobe_dark_source_;
  std::array<std::string, 3> select_outputs_;
  std::array<int, 3> select_bits_{-1, -1, -1};  // last value written per select line; -1 unknown
  bool strobe_lit_ = false;
  int selected_led_ = kNoLed;
  // Frame accounting.
  bool have_frame_id_ = false;
  std::uint64_t last_frame_id_ = 0;
  std::uint64_t discarded_frames_ = 0;
  int silent_triggers_ = 0;  // frame timeouts since the last frame
  CameraStats stats_;
  // Reconnection. A lost connection is released on releaser_ (Aravis waits out its GVCP retries
  // for every command to the absent camera, about 10 s with 0.8's defaults), off the frame path;
  // the camera is reopened only once that is done.
  std::thread releaser_;
  std::atomic<bool> releasing_{false};
  std::int64_t next_reconnect_ns_ = 0;
  std::chrono::milliseconds backoff_{0};
};

}  // namespace mfcd::hal
