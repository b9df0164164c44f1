#include "daemon/gripper_camera.hpp"

#include <cstring>
#include <stdexcept>

#include "mfcd/hal/v4l2_camera.hpp"

namespace mfcd::daemon {

namespace {

// A V4L2 device, streaming only while it takes an image: the first frame after VIDIOC_STREAMON
// was exposed after the call began, so a check never sees a frame buffered before the robot
// brought the part.
class V4L2GripperCamera final : public GripperCamera {
 public:
  explicit V4L2GripperCamera(const GripperCheckSettings& s) : camera_(config(s)) {
    camera_.configure();
    image_.allocate(camera_.format());
  }
  void capture(const Eigen::Isometry3d&, cv::Mat1b& out) override {
    camera_.activate();
    try {
      hal::FrameInfo info;
      camera_.read(image_, info);
    } catch (...) {
      camera_.deactivate();
      throw;
    }
    camera_.deactivate();
    const hal::ImageFormat& f = image_.format();
    if (out.cols != f.width || out.rows != f.height)
      throw std::runtime_error(describe() + ": the image is " + std::to_string(f.width) + "x" +
                               std::to_string(f.height) + ", gripper_check.camera says " + std::to_string(out.cols) +
                               "x" + std::to_string(out.rows));
    for (int y = 0; y < f.height; ++y) std::memcpy(out.ptr(y), image_.row(y), static_cast<std::size_t>(f.width));
  }
  std::string describe() const override { return "gripper camera " + camera_.describe(); }

 private:
  static hal::V4L2CameraConfig config(const GripperCheckSettings& s) {
    hal::V4L2CameraConfig v;
    v.device = s.device;
    v.width = s.width;
    v.height = s.height;
    v.bits_per_pixel = 8;
    v.buffer_count = 2;
    v.dequeue_timeout = std::chrono::milliseconds(s.dequeue_timeout_ms);
    return v;
  }
  hal::V4L2Camera camera_;
  hal::Image image_;
};

class SimulatedGripperCamera final : public GripperCamera {
 public:
  SimulatedGripperCamera(const GripperCheckSettings& s, SimulatedWorld& world)
      : camera_(gripper_pinhole(s)), world_(world) {}
  void capture(const Eigen::Isometry3d& camera_T_ideal, cv::Mat1b& out) override {
    world_.capture_gripper(camera_, camera_T_ideal, out);
  }
  std::string describe() const override { return "simulated gripper camera"; }

 private:
  vision::PinholeCamera camera_;
  SimulatedWorld& world_;
};

}  // namespace

vision::PinholeCamera gripper_pinhole(const GripperCheckSettings& s) {
  vision::PinholeCamera c;
  c.image_size = {s.width, s.height};
  c.K = cv::Matx33d(s.fx, 0, s.cx, 0, s.fy, s.cy, 0, 0, 1);
  return c;
}

std::unique_ptr<GripperCamera> make_gripper_camera(const DaemonConfig& config, FrameSource& cell) {
  const GripperCheckSettings& s = config.gripper_check;
  if (!s.enabled) return nullptr;
  if (s.type == GripperCameraType::V4L2) return std::make_unique<V4L2GripperCamera>(s);
  SimulatedWorld* world = cell.simulation();
  if (!world)
    throw std::runtime_error(config.source + ": gripper_check.camera.type simulated needs the simulated cell");
  return std::make_unique<SimulatedGripperCamera>(s, *world);
}

}  // namespace mfcd::daemon
