#pragma once
// Camera: one grey image per read(). Backends: V4L2Camera (v4l2_camera.hpp) and SimulatedCamera
// (simulated.hpp). Lifecycle as in ros2_control: configure() opens and allocates, activate() starts
// streaming, deactivate() stops it; the control loop only calls read().
#include <cstdint>
#include <string>

#include "mfcd/hal/image.hpp"

namespace mfcd::hal {

struct FrameInfo {
  std::int64_t timestamp_ns = 0;  // CLOCK_MONOTONIC, as stamped by the driver
  std::uint32_t sequence = 0;     // driver frame counter: gaps are dropped frames
};

struct CameraStats {
  std::uint64_t frames = 0;          // frames delivered by read()
  std::uint64_t dropped_frames = 0;  // sequence-number gaps
  std::uint64_t error_buffers = 0;   // buffers flagged V4L2_BUF_FLAG_ERROR, re-queued
  std::uint64_t timeouts = 0;        // dequeue watchdog expiries
  std::uint64_t reconnects = 0;      // successful re-opens after ENODEV
};

// Frames a driver skipped between two delivered sequence numbers. The counter is 32 bits and
// wraps; a number that repeats or goes backwards (a driver that restarts its count, or vivid
// filling two buffers in one frame period on a starved machine) is a resynchronisation, not
// four billion drops.
constexpr std::uint64_t frames_missed_between(std::uint32_t previous, std::uint32_t current) {
  const std::uint32_t step = current - previous;  // modulo 2^32: forward across a wrap too
  return step != 0 && step < 0x80000000u ? step - 1u : 0u;
}

class Camera {
 public:
  virtual ~Camera() = default;
  virtual void configure() = 0;
  virtual void activate() = 0;
  virtual void deactivate() = 0;
  // Blocks until the next frame (bounded by the dequeue watchdog) and converts it into `out`, which
  // must have format(). Throws HalError on timeout, unplug, or lifecycle misuse.
  virtual void read(Image& out, FrameInfo& info) = 0;
  virtual ImageFormat format() const = 0;
  // Time from the start of a frame's exposure to its timestamp (0 for start-of-exposure stamps,
  // about one frame period for end-of-frame stamps). The sequencer uses it for the on-window check.
  virtual std::int64_t exposure_lead_ns() const = 0;
  virtual const CameraStats& stats() const = 0;
  virtual std::string describe() const = 0;  // "V4L2 /dev/video0 (vivid)", for messages
};

}  // namespace mfcd::hal
