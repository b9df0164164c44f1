// Applying a calibration: atomic replacement, the previous file kept, rollback, and a
// failure at any step leaving the old file as it was.
#include "vision/calib/store.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

using namespace mfcd::vision;
using namespace mfcd::vision::calib;
namespace fs = std::filesystem;

namespace {

CameraConfig sim_config() { return load_camera_config(MFC_SOURCE_DIR "/config/camera-sim.yaml"); }

std::string slurp(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

fs::path fresh_dir(const std::string& name) {
  const fs::path d = fs::path(MFC_BINARY_DIR) / "test-calib-store" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

size_t files_in(const fs::path& d) {
  size_t n = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(d)) ++n;
  return n;
}

CameraConfig calibrated(double fx) {
  CameraConfig c = sim_config();
  c.camera.K(0, 0) = fx;
  HandEye h;
  h.mode = HandEye::Mode::eye_to_hand;
  h.camera_pose = cv::Matx44d(0, 1, 0, 10.5, -1, 0, 0, -2.25, 0, 0, 1, 900, 0, 0, 0, 1);
  h.reprojection_rms_px = 0.21;
  h.residual_rms_mm = 0.1;
  h.views = 15;
  c.hand_eye = h;
  return c;
}

}  // namespace

TEST(CalibrationStore, ApplyKeepsThePreviousAndRollbackRestoresIt) {
  const fs::path dir = fresh_dir("apply");
  const fs::path file = dir / "camera.yaml";
  fs::copy_file(MFC_SOURCE_DIR "/config/camera-sim.yaml", file);
  const std::string original = slurp(file);
  CalibrationStore store(file);
  EXPECT_FALSE(store.previous().has_value());

  store.apply(calibrated(1123.5));
  const CameraConfig now = *store.current();
  EXPECT_EQ(now.camera.fx(), 1123.5);
  ASSERT_TRUE(now.hand_eye.has_value());
  EXPECT_EQ(now.hand_eye->mode, HandEye::Mode::eye_to_hand);
  EXPECT_EQ(now.hand_eye->camera_pose, calibrated(0).hand_eye->camera_pose);
  EXPECT_EQ(now.hand_eye->views, 15);
  EXPECT_EQ(slurp(store.previous_file()), original);  // byte for byte: the old file itself
  EXPECT_EQ(files_in(dir), 2u) << "temporary files left behind";

  store.rollback();
  EXPECT_EQ(store.current()->camera.fx(), 1100.0);
  EXPECT_FALSE(store.current()->hand_eye.has_value());
  EXPECT_EQ(store.previous()->camera.fx(), 1123.5);  // a second rollback would undo the first
  store.rollback();
  EXPECT_EQ(store.current()->camera.fx(), 1123.5);
}

TEST(CalibrationStore, AFailureAtAnyStepLeavesTheOldFile) {
  for (const std::string failing : {"temp-written", "temp-synced", "previous-kept", "before-rename"}) {
    const fs::path dir = fresh_dir("fail-" + failing);
    const fs::path file = dir / "camera.yaml";
    fs::copy_file(MFC_SOURCE_DIR "/config/camera-sim.yaml", file);
    const std::string original = slurp(file);
    CalibrationStore store(file, [&](const std::string& step) {
      if (step == failing) throw std::runtime_error("injected failure at " + step);
    });
    EXPECT_THROW(store.apply(calibrated(1200)), std::runtime_error) << failing;
    EXPECT_EQ(slurp(file), original) << failing;
    for (const auto& e : fs::directory_iterator(dir))
      EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << failing << ": " << e.path();
  }
}

TEST(CalibrationStore, InvalidConfigOrUnwritableDirectoryChangesNothing) {
  const fs::path dir = fresh_dir("invalid");
  const fs::path file = dir / "camera.yaml";
  fs::copy_file(MFC_SOURCE_DIR "/config/camera-sim.yaml", file);
  const std::string original = slurp(file);
  CalibrationStore store(file);
  CameraConfig bad = sim_config();
  bad.camera.K(0, 0) = -5;  // fails validation before anything is written
  try {
    store.apply(bad);
    FAIL() << "invalid config applied";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("camera_matrix"), std::string::npos) << e.what();
  }
  EXPECT_EQ(slurp(file), original);
  EXPECT_EQ(files_in(dir), 1u);

  // A directory that does not exist stands in for an unwritable one (tests may run as root,
  // which ignores permission bits).
  CalibrationStore nowhere(dir / "missing" / "camera.yaml");
  EXPECT_THROW(nowhere.apply(sim_config()), std::runtime_error);
  EXPECT_THROW(nowhere.rollback(), std::runtime_error);
  EXPECT_THROW(store.rollback(), std::runtime_error);  // nothing applied yet: no previous
  EXPECT_EQ(slurp(file), original);
}

TEST(CalibrationStore, HandEyeSectionIsOptionalAndValidated) {
  const fs::path dir = fresh_dir("yaml");
  // Old files without the section load as before.
  EXPECT_FALSE(load_camera_config(MFC_SOURCE_DIR "/config/camera-sim.yaml").hand_eye.has_value());
  CameraConfig c = calibrated(1100);
  c.hand_eye->camera_pose(0, 0) = 2;  // not a rotation
  EXPECT_THROW(save_camera_config(c, dir / "bad.yaml"), std::runtime_error);
  write_camera_config_atomically(calibrated(1100), dir / "good.yaml");
  std::string text = slurp(dir / "good.yaml");
  const auto at = text.find("eye_to_hand");
  ASSERT_NE(at, std::string::npos);
  text.replace(at, 11, "eye_on_desk");
  std::ofstream(dir / "typo.yaml") << text;
  try {
    load_camera_config(dir / "typo.yaml");
    FAIL() << "bad mode accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("hand_eye.mode"), std::string::npos) << e.what();
  }
}
