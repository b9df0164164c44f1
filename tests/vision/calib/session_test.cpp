// The daemon's calibration flow: views -> compute (figures, nothing written) -> apply on
// confirmation -> rollback.
#include "vision/calib/session.hpp"
#include "vision/calib/sim_board.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <sstream>

using namespace mfcd::vision;
using namespace mfcd::vision::calib;
namespace fs = std::filesystem;

namespace {
std::string slurp(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}
}  // namespace

TEST(CalibrationSession, HandEyeIsWrittenOnlyOnApplyAndRollsBack) {
  const fs::path dir = fs::path(MFC_BINARY_DIR) / "test-calib-session";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path file = dir / "camera.yaml";
  fs::copy_file(MFC_SOURCE_DIR "/config/camera-sim.yaml", file);
  const std::string original = slurp(file);

  const CameraConfig cfg = load_camera_config(file);
  const CheckerBoard board{9, 6, 10.0};
  SimBoardScene scene(cfg, board);
  std::mt19937 rng(12);
  const SimHandEyeCell cell = make_sim_hand_eye_cell(scene, HandEyeMode::eye_in_hand, 9, cfg.working_distance_mm, rng);

  auto s = CalibrationSession::hand_eye(file, HandEyeMode::eye_in_hand, board);
  EXPECT_FALSE(s.add_view(scene.render(cell.views[0].T_camera_board, 1)).accepted) << "view without a pose";
  for (size_t i = 0; i < 4; ++i)
    ASSERT_TRUE(s.add_view(scene.render(cell.views[i].T_camera_board, 10 + i), cell.views[i].flange).accepted);
  EXPECT_THROW(s.compute(), CalibrationError);  // too few views
  EXPECT_FALSE(s.has_pending());
  EXPECT_THROW(s.apply(), CalibrationError);
  for (size_t i = 4; i < cell.views.size(); ++i)
    ASSERT_TRUE(s.add_view(scene.render(cell.views[i].T_camera_board, 10 + i), cell.views[i].flange).accepted);
  const std::string figures = s.compute();
  EXPECT_NE(figures.find("T_flange_camera"), std::string::npos) << figures;
  EXPECT_EQ(slurp(file), original) << "computed but not confirmed: nothing written";
  ASSERT_TRUE(s.pending().hand_eye.has_value());
  const double err = cv::norm(translation_of(s.pending().hand_eye->camera_pose) - translation_of(cell.hand_eye_true));
  EXPECT_LT(err, 0.5);

  const SimHandEyeCell more = make_sim_hand_eye_cell(scene, HandEyeMode::eye_in_hand, 1, cfg.working_distance_mm, rng);
  const HandEyeCheck c = s.check(scene.render(more.views[0].T_camera_board, 77), more.views[0].flange);
  EXPECT_TRUE(c.board_found) << c.reason;
  EXPECT_LT(c.origin_error_mm, 1.0);

  s.apply();
  const CameraConfig written = load_camera_config(file);
  ASSERT_TRUE(written.hand_eye.has_value());
  EXPECT_EQ(written.hand_eye->camera_pose, s.pending().hand_eye->camera_pose);
  EXPECT_EQ(written.hand_eye->views, 9);
  EXPECT_EQ(slurp(fs::path(file.string() + ".previous")), original);

  CalibrationSession::rollback(file);
  EXPECT_FALSE(load_camera_config(file).hand_eye.has_value());
  EXPECT_THROW(CalibrationSession::intrinsics(dir / "absent.yaml", board), std::runtime_error);
}
