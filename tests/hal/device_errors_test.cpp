// The real backends' errors when the hardware is not there (no driver needed): they must name the
// device and say what to check. With drivers, tests/hil covers the rest.
#include <gtest/gtest.h>

#include <string>

#include "catch_hal.hpp"
#include "mfcd/hal/error.hpp"
#include "mfcd/hal/gpiod_light_ring.hpp"
#include "mfcd/hal/v4l2_camera.hpp"

namespace mfcd::hal {
namespace {

using mfcd::hal::test::catch_hal;

TEST(V4L2CameraErrors, MissingNodeNamesTheDeviceAndWhatToCheck) {
  V4L2CameraConfig cfg;
  cfg.device = "/dev/video-mfcd-does-not-exist";
  V4L2Camera camera(cfg);
  const HalError e = catch_hal([&] { camera.configure(); });
  EXPECT_EQ(e.code(), ErrorCode::DeviceMissing);
  EXPECT_NE(std::string(e.what()).find(cfg.device), std::string::npos) << e.what();
  EXPECT_NE(std::string(e.what()).find("check"), std::string::npos) << e.what();
}

TEST(V4L2CameraErrors, NonV4L2NodeIsRefused) {
  V4L2CameraConfig cfg;
  cfg.device = "/dev/null";  // a character device that does not speak V4L2
  V4L2Camera camera(cfg);
  const HalError e = catch_hal([&] { camera.configure(); });
  EXPECT_NE(std::string(e.what()).find("/dev/null"), std::string::npos) << e.what();
  EXPECT_NE(std::string(e.what()).find("VIDIOC_QUERYCAP"), std::string::npos) << e.what();
}

TEST(V4L2CameraErrors, LifecycleMisuse) {
  V4L2Camera camera(V4L2CameraConfig{});
  EXPECT_THROW(camera.activate(), HalError);
  Image img(ImageFormat{8, 8, 8});
  FrameInfo info;
  EXPECT_THROW(camera.read(img, info), HalError);
}

TEST(GpiodLightRingErrors, MissingChipNamesTheChip) {
  GpiodLightRingConfig cfg;
  cfg.chip = "mfcd-no-such-chip";
  GpiodLightRing ring(cfg);
  const HalError e = catch_hal([&] { ring.configure(); });
  EXPECT_EQ(e.code(), ErrorCode::DeviceMissing);
  EXPECT_NE(std::string(e.what()).find("mfcd-no-such-chip"), std::string::npos) << e.what();
  EXPECT_NE(std::string(e.what()).find("gpiodetect"), std::string::npos) << e.what();
  EXPECT_THROW(ring.set(1), HalError);  // nothing requested: refused, not a crash
}

}  // namespace
}  // namespace mfcd::hal
