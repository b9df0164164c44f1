// Intrinsics end to end: renders of the plate at spread poses -> detected corners ->
// calibrateCamera; the recovered pinhole must match the simulated camera. Bad views are
// rejected, bad sessions are clear errors.
#include "vision/calib/intrinsics.hpp"
#include "vision/calib/sim_board.hpp"

#include <gtest/gtest.h>

#include <random>

using namespace mfcd::vision;
using namespace mfcd::vision::calib;

namespace {

CameraConfig sim_config() { return load_camera_config(MFC_SOURCE_DIR "/config/camera-sim.yaml"); }

}  // namespace

TEST(IntrinsicsCalibration, RecoversTheSimulatedCameraWithinHalfAPercent) {
  const CameraConfig cfg = sim_config();
  const CheckerBoard board{9, 6, 10.0};
  SimBoardScene scene(cfg, board);
  std::mt19937 rng(3);
  // The f = 1100 px lens sees a narrow field: strongly tilted, near views pin down f and
  // the principal point.
  const auto poses = random_board_views(scene, 20, cfg.working_distance_mm, rng, 60, 0.7, 1.1);
  IntrinsicsCalibration cal(board);
  for (size_t i = 0; i < poses.size(); ++i) {
    const ViewReport v = cal.add_view(scene.render(poses[i], 1000 + i), "sim " + std::to_string(i));
    ASSERT_TRUE(v.accepted) << v.label << ": " << v.reason;
  }
  const IntrinsicsResult r = cal.compute();
  std::cout << r.summary();
  const PinholeCamera& truth = cfg.camera;
  EXPECT_NEAR(r.camera.fx(), truth.fx(), 0.005 * truth.fx());
  EXPECT_NEAR(r.camera.fy(), truth.fy(), 0.005 * truth.fy());
  EXPECT_NEAR(r.camera.cx(), truth.cx(), 0.005 * truth.cx());
  EXPECT_NEAR(r.camera.cy(), truth.cy(), 0.005 * truth.cy());
  EXPECT_LT(r.rms_px, 0.5);
  EXPECT_EQ(r.used_views, 20);
  ASSERT_EQ(r.views.size(), 20u);
  for (const auto& v : r.views) EXPECT_FALSE(v.rejected) << v.label;
  EXPECT_EQ(r.camera.image_size, truth.image_size);
}

TEST(IntrinsicsCalibration, ExactCornersGiveTheExactCameraAndABadViewIsRejected) {
  const CameraConfig cfg = sim_config();
  const CheckerBoard board{9, 6, 10.0};
  SimBoardScene scene(cfg, board);
  std::mt19937 rng(8);
  const auto poses = random_board_views(scene, 10, cfg.working_distance_mm, rng, 50);
  IntrinsicsCalibration cal(board);
  for (size_t i = 0; i < poses.size(); ++i) {
    auto corners = scene.project_corners(poses[i]);
    if (i == 4)  // a view whose corners were mis-detected by several pixels
      for (size_t k = 0; k < corners.size(); k += 3) corners[k] += cv::Point2f(4.f, -3.f);
    ASSERT_TRUE(cal.add_corners(corners, cfg.camera.image_size).accepted);
  }
  const IntrinsicsResult r = cal.compute();
  EXPECT_TRUE(r.views[4].rejected);
  EXPECT_EQ(r.used_views, 9);
  EXPECT_NEAR(r.camera.fx(), 1100, 0.01);
  EXPECT_NEAR(r.camera.fy(), 1100, 0.01);
  EXPECT_NEAR(r.camera.cx(), 319.5, 0.01);
  EXPECT_NEAR(r.camera.cy(), 239.5, 0.01);
  EXPECT_LT(r.rms_px, 1e-3);
  EXPECT_NE(r.summary().find("REJECTED"), std::string::npos);
}

TEST(IntrinsicsCalibration, TooFewViewsAndMissingBoardAreClearErrors) {
  const CameraConfig cfg = sim_config();
  const CheckerBoard board{9, 6, 10.0};
  SimBoardScene scene(cfg, board);
  std::mt19937 rng(9);
  IntrinsicsCalibration cal(board);
  for (const auto& p : random_board_views(scene, 3, cfg.working_distance_mm, rng))
    ASSERT_TRUE(cal.add_corners(scene.project_corners(p), cfg.camera.image_size).accepted);
  const ViewReport blank = cal.add_view(cv::Mat1b(480, 640, uint8_t{200}), "blank.png");
  EXPECT_FALSE(blank.accepted);
  EXPECT_NE(blank.reason.find("not found"), std::string::npos) << blank.reason;
  // Another board size than the one asked for is "not found" too.
  IntrinsicsCalibration seven_by_five(CheckerBoard{7, 5, 10});
  EXPECT_FALSE(seven_by_five.add_view(scene.render(random_board_views(scene, 1, 300, rng)[0])).accepted);
  const ViewReport wrong =
      cal.add_corners(scene.project_corners(random_board_views(scene, 1, 300, rng)[0]), {800, 600});
  EXPECT_FALSE(wrong.accepted);
  EXPECT_NE(wrong.reason.find("differs"), std::string::npos) << wrong.reason;
  EXPECT_EQ(cal.view_count(), 3u);
  try {
    cal.compute();
    FAIL() << "3 views accepted";
  } catch (const CalibrationError& e) {
    EXPECT_NE(std::string(e.what()).find("too few views"), std::string::npos) << e.what();
  }
}
