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
#include "vision/camera/camera.hpp"

namespace mfcd::daemon {

// What only the simulated cell can do, below the FrameSource interface: its ground truth, the
// robot taking a part, a fresh bin, the calibration plate. A real cell has none of it.
class SimulatedWorld {
 public:
  virtual ~SimulatedWorld() = default;
  // The bin's ground truth for the frame set just captured.
  virtual void truth(SimTruth& out) const = 0;
  // The robot takes the part nearest `t_cam_mm` (mm, in the frame of the camera that saw it: on a
  // flange at `base_T_flange` when the cell moves the camera, see move_camera), gripping it where
  // vision put it (R_cam, t_cam_mm: model -> that camera). May allocate.
  virtual void remove_picked(const cv::Matx33d& R_cam, const cv::Vec3d& t_cam_mm,
                             const Eigen::Isometry3d* base_T_flange) = 0;
  // The gripper camera's image (8-bit, camera.image_size) of the part taken last, held at
  // camera_T_ideal (model -> that camera: where a perfect pick puts it) displaced by the pick's
  // pose error (the true pose relative to vision's) and simulation.gripper.slip; an empty gripper
  // when that pick took nothing or simulation.gripper.drop_every dropped it. May allocate.
  virtual void capture_gripper(const vision::PinholeCamera& camera, const Eigen::Isometry3d& camera_T_ideal,
                               cv::Mat1b& out) = 0;
  // The camera of the next capture is on a flange at `base_T_flange` (nullptr: not known). Moves
  // the simulated camera when simulation.eye_in_hand_view is set, otherwise does nothing. May
  // allocate (it re-stages the scene).
  virtual void move_camera(const Eigen::Isometry3d* base_T_flange) = 0;
  virtual void refill() = 0;
  // Shows the calibration plate as asked for the next capture(s); Kind::None brings the bin back.
  // Throws std::runtime_error when the cell cannot show it.
  virtual void show_plate(const PlateRequest& plate) = 0;
  // The simulated devices, for fault injection below the HAL's interfaces (the fault tests).
  virtual hal::SimulatedCamera& simulated_camera() = 0;
  virtual hal::SimulatedLightRing& simulated_lights() = 0;
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
std::unique_ptr<FrameSource> make_frame_source(const DaemonConfig& config);

// Drives every LED line of `config` off and releases it (mfcd --leds-off, the unit's
// ExecStopPost=: after a crash or SIGKILL a GPIO line keeps the level it was last driven to).
// Returns what was done; throws hal::HalError naming the chip and line when they cannot be driven.
std::string switch_leds_off(const DaemonConfig& config);

}  // namespace mfcd::daemon
