#pragma once
// Where FrameSets come from: the HAL sequencer over real devices (V4L2 + libgpiod) or over the
// simulated cell (SimulatedCamera + SimulatedLightRing rendering a bin of CAD parts). Created and
// used only by the acquisition thread (the simulated cell's EGL context is bound to it).
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "daemon/config.hpp"
#include "daemon/cycle.hpp"
#include "mfcd/hal/sequencer.hpp"
#include "mfcd/hal/simulated.hpp"

namespace mfcd::daemon {

// What only the simulated cell can do, below the FrameSource interface: its ground truth, the
// robot taking a part, a fresh bin, the calibration plate. A real cell has none of it.
class SimulatedWorld {
 public:
  virtual ~SimulatedWorld() = default;
  // The bin's ground truth for the frame set just captured.
  virtual void truth(SimTruth& out) const = 0;
  // The robot takes the part nearest `t_cam_mm` (mm, in the frame of the camera that saw it: on a
  // flange at `base_T_flange` when the cell moves the camera, see moveCamera). May allocate.
  virtual void removePicked(const cv::Vec3d& t_cam_mm, const Eigen::Isometry3d* base_T_flange) = 0;
  // The camera of the next capture is on a flange at `base_T_flange` (nullptr: not known). Moves
  // the simulated camera when simulation.eye_in_hand_view is set, otherwise does nothing. May
  // allocate (it re-stages the scene).
  virtual void moveCamera(const Eigen::Isometry3d* base_T_flange) = 0;
  virtual void refill() = 0;
  // Shows the calibration plate as asked for the next capture(s); Kind::None brings the bin back.
  // Throws std::runtime_error when the cell cannot show it.
  virtual void showPlate(const PlateRequest& plate) = 0;
  // The simulated devices, for fault injection below the HAL's interfaces (the fault tests).
  virtual hal::SimulatedCamera& simulatedCamera() = 0;
  virtual hal::SimulatedLightRing& simulatedLights() = 0;
};

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  virtual void activate() = 0;             // configure + activate the devices
  virtual void deactivate() noexcept = 0;  // LEDs off, streaming stopped
  // One multi-flash capture; throws hal::HalError. Valid until the next capture().
  virtual const hal::FrameSet& capture() = 0;
  virtual hal::ImageFormat format() const = 0;
  virtual hal::LedMask leds() const = 0;
  virtual std::string describe() const = 0;
  // The simulated world behind this source, or nullptr for real devices.
  virtual SimulatedWorld* simulation() noexcept { return nullptr; }
};

using FrameSourceFactory = std::function<std::unique_ptr<FrameSource>(const DaemonConfig&)>;

// Builds the source the configuration asks for. Throws (HalError, std::runtime_error) naming the
// device or file.
std::unique_ptr<FrameSource> makeFrameSource(const DaemonConfig& config);

// Drives every LED line of `config` off and releases it (mfcd --leds-off, the unit's
// ExecStopPost=: after a crash or SIGKILL a GPIO line keeps the level it was last driven to).
// Returns what was done; throws hal::HalError naming the chip and line when they cannot be driven.
std::string switchLedsOff(const DaemonConfig& config);

}  // namespace mfcd::daemon
