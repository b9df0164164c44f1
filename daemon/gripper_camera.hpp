#pragma once
// The gripper camera (config gripper_check, paper Sec. 4.6): a standard camera on the arm, fixed
// to the tool, that takes one grey image of what the gripper holds when the PLC sends CHECK_GRIP.
// Backends: a V4L2 device, or the simulated cell rendering the part its robot took last. Made,
// used and destroyed by the acquisition thread (the simulated cell's EGL context is bound to it).
#include <memory>
#include <string>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "daemon/config.hpp"
#include "daemon/frame_source.hpp"
#include "vision/camera/camera.hpp"

namespace mfcd::daemon {

class GripperCamera {
 public:
  virtual ~GripperCamera() = default;
  // One image into `out` (already camera().image_size, 8-bit), taken after the call began.
  // `camera_T_ideal` is where a perfect pick puts the part (model -> this camera, mm): only the
  // simulated backend uses it. Throws (hal::HalError, std::runtime_error) naming the device.
  virtual void capture(const Eigen::Isometry3d& camera_T_ideal, cv::Mat1b& out) = 0;
  virtual std::string describe() const = 0;
};

// The configured gripper camera's pinhole model.
vision::PinholeCamera gripper_pinhole(const GripperCheckSettings& settings);

// The backend config.gripper_check asks for; nullptr when the section is absent. The simulated
// one needs `cell`'s simulated world (std::runtime_error otherwise).
std::unique_ptr<GripperCamera> make_gripper_camera(const DaemonConfig& config, FrameSource& cell);

}  // namespace mfcd::daemon
