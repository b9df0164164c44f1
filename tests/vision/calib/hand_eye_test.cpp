// Hand-eye end to end on renders from a simulated robot, both set-ups; the joint refinement
// against cv::calibrateHandEye and against a direct reprojection with cv::projectPoints;
// degenerate motion and too few views.
#include "vision/calib/hand_eye.hpp"
#include "vision/calib/sim_board.hpp"

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>

#include <random>

using namespace mfcd::vision;
using namespace mfcd::vision::calib;

namespace {

CameraConfig sim_config() { return load_camera_config(MFC_SOURCE_DIR "/config/camera-sim.yaml"); }

struct Errors {
  double mm, deg;
};
Errors transform_error(const cv::Matx44d& a, const cv::Matx44d& b) {
  return {cv::norm(translation_of(a) - translation_of(b)), rotation_angle_deg(rotation_of(a), rotation_of(b))};
}

// Slow twin of HandEyeCalibration::reprojection_rms_px: compose the 4x4 chain per view and
// project with cv::projectPoints.
double direct_rms(HandEyeMode mode, const PinholeCamera& cam, const CheckerBoard& board, const HandEyeResult& r,
                  const std::vector<cv::Matx44d>& flanges, const std::vector<std::vector<cv::Point2f>>& corners) {
  const auto obj = board.object_points();
  double sum2 = 0;
  size_t count = 0;
  for (size_t i = 0; i < flanges.size(); ++i) {
    const cv::Matx44d Tcb = mode == HandEyeMode::eye_in_hand ? r.hand_eye.inv() * flanges[i].inv() * r.board
                                                             : r.hand_eye.inv() * flanges[i] * r.board;
    cv::Mat rvec;
    cv::Rodrigues(cv::Mat(cv::Matx33d(Tcb.get_minor<3, 3>(0, 0))), rvec);
    const cv::Mat tvec = (cv::Mat_<double>(3, 1) << Tcb(0, 3), Tcb(1, 3), Tcb(2, 3));
    std::vector<cv::Point2f> proj;
    cv::projectPoints(obj, rvec, tvec, cv::Mat(cam.K), cv::Mat(cam.distortion), proj);
    for (size_t k = 0; k < proj.size(); ++k) {
      const cv::Point2f d = proj[k] - corners[i][k];
      sum2 += d.dot(d);
      ++count;
    }
  }
  return std::sqrt(sum2 / static_cast<double>(count));
}

void run_end_to_end(HandEyeMode mode, uint32_t seed) {
  const CameraConfig cfg = sim_config();
  const CheckerBoard board{9, 6, 10.0};
  SimBoardScene scene(cfg, board);
  std::mt19937 rng(seed);
  const SimHandEyeCell cell = make_sim_hand_eye_cell(scene, mode, 15, cfg.working_distance_mm, rng);
  HandEyeCalibration cal(mode, cfg.camera, board);
  std::vector<cv::Matx44d> flanges;
  std::vector<std::vector<cv::Point2f>> corners;
  for (size_t i = 0; i < cell.views.size(); ++i) {
    const ViewReport v = cal.add_view(scene.render(cell.views[i].T_camera_board, seed * 100 + i), cell.views[i].flange,
                                      "pose " + std::to_string(i));
    ASSERT_TRUE(v.accepted) << v.label << ": " << v.reason;
    flanges.push_back(cell.views[i].flange.matrix());
    corners.push_back(v.corners);
  }
  const HandEyeResult r = cal.compute();
  std::cout << r.summary();
  const Errors x = transform_error(r.hand_eye, cell.hand_eye_true);
  const Errors y = transform_error(r.board, cell.board_true);
  std::cout << "hand-eye error " << x.mm << " mm " << x.deg << " deg; board " << y.mm << " mm " << y.deg << " deg\n";
  EXPECT_LT(x.mm, 0.5);
  EXPECT_LT(x.deg, 0.1);
  EXPECT_LT(r.rms_px, 0.5);

  // The joint refinement lowers the residual of the best closed-form solution, and the
  // residual it reports is the one a direct projection of every corner gives.
  EXPECT_LT(r.rms_px, r.initial_rms_px);
  EXPECT_NEAR(direct_rms(mode, cfg.camera, board, r, flanges, corners), r.rms_px, 1e-4);
  // The same views without refinement: the closed-form answer alone, no closer to the truth.
  HandEyeOptions closed_form;
  closed_form.refine = false;
  HandEyeCalibration plain(mode, cfg.camera, board, closed_form);
  for (size_t i = 0; i < corners.size(); ++i) ASSERT_TRUE(plain.add_corners(corners[i], flanges[i]).accepted);
  const HandEyeResult p = plain.compute();
  EXPECT_DOUBLE_EQ(p.rms_px, r.initial_rms_px);
  const Errors px = transform_error(p.hand_eye, cell.hand_eye_true);
  std::cout << "closed form alone (" << p.initial_method << "): " << px.mm << " mm " << px.deg << " deg\n";
  EXPECT_LE(x.mm, px.mm + 0.05);
  EXPECT_LE(x.deg, px.deg + 0.01);

  // Check step: a new robot pose, board predicted vs observed.
  const SimHandEyeCell more = make_sim_hand_eye_cell(scene, mode, 1, cfg.working_distance_mm, rng);
  const HandEyeCheck c = cal.check(r, scene.render(more.views[0].T_camera_board, 99), more.views[0].flange.matrix());
  std::cout << c.summary();
  ASSERT_TRUE(c.board_found) << c.reason;
  EXPECT_LT(c.origin_error_mm, 1.0);
  EXPECT_LT(c.rotation_error_deg, 0.2);
  EXPECT_LT(c.reprojection_rms_px, 1.0);
}

}  // namespace

TEST(HandEyeCalibration, EyeInHandRecoversTheTrueTransform) { run_end_to_end(HandEyeMode::eye_in_hand, 5); }

TEST(HandEyeCalibration, EyeToHandRecoversTheTrueTransform) { run_end_to_end(HandEyeMode::eye_to_hand, 6); }

TEST(HandEyeCalibration, ExactCornersGiveTheExactTransform) {
  // Noise-free projected corners: both the closed form and the refinement must land on the
  // truth (to the robot pose's 0.001 rounding), for both modes.
  const CameraConfig cfg = sim_config();
  const CheckerBoard board{9, 6, 10.0};
  SimBoardScene scene(cfg, board);
  for (HandEyeMode mode : {HandEyeMode::eye_in_hand, HandEyeMode::eye_to_hand}) {
    std::mt19937 rng(21);
    const SimHandEyeCell cell = make_sim_hand_eye_cell(scene, mode, 10, cfg.working_distance_mm, rng);
    HandEyeCalibration cal(mode, cfg.camera, board);
    for (const auto& v : cell.views)
      ASSERT_TRUE(cal.add_corners(scene.project_corners(v.T_camera_board), v.flange.matrix()).accepted);
    const HandEyeResult r = cal.compute();
    const Errors x = transform_error(r.hand_eye, cell.hand_eye_true);
    EXPECT_LT(x.mm, 0.01) << to_string(mode);
    EXPECT_LT(x.deg, 0.001) << to_string(mode);
    EXPECT_LT(r.rms_px, 1e-3) << to_string(mode);
  }
}

TEST(HandEyeCalibration, ReprojectionResidualMatchesDirectProjectionForRandomTransforms) {
  const CameraConfig cfg = sim_config();
  const CheckerBoard board{9, 6, 10.0};
  SimBoardScene scene(cfg, board);
  std::mt19937 rng(31);
  std::normal_distribution<double> n(0, 1);
  for (HandEyeMode mode : {HandEyeMode::eye_in_hand, HandEyeMode::eye_to_hand}) {
    const SimHandEyeCell cell = make_sim_hand_eye_cell(scene, mode, 8, cfg.working_distance_mm, rng);
    HandEyeCalibration cal(mode, cfg.camera, board);
    std::vector<cv::Matx44d> flanges;
    std::vector<std::vector<cv::Point2f>> corners;
    for (const auto& v : cell.views) {
      corners.push_back(scene.project_corners(v.T_camera_board));
      for (auto& c : corners.back())
        c += cv::Point2f(static_cast<float>(0.3 * n(rng)), static_cast<float>(0.3 * n(rng)));
      flanges.push_back(v.flange.matrix());
      ASSERT_TRUE(cal.add_corners(corners.back(), flanges.back()).accepted);
    }
    for (int trial = 0; trial < 20; ++trial) {
      // X, Y perturbed by up to a few mm / degrees: residuals from sub-pixel to tens of px.
      const double s = trial / 4.0;
      HandEyeResult r;
      r.mode = mode;
      r.hand_eye =
          cell.hand_eye_true * make_transform(rotation_from_vector(cv::Vec3d(n(rng), n(rng), n(rng)) * 0.01 * s),
                                              cv::Vec3d(n(rng), n(rng), n(rng)) * s);
      r.board = cell.board_true * make_transform(rotation_from_vector(cv::Vec3d(n(rng), n(rng), n(rng)) * 0.01 * s),
                                                 cv::Vec3d(n(rng), n(rng), n(rng)) * s);
      const double fast = cal.reprojection_rms_px(r.hand_eye, r.board);
      const double slow = direct_rms(mode, cfg.camera, board, r, flanges, corners);
      EXPECT_NEAR(fast, slow, 1e-4 * std::max(1.0, slow)) << to_string(mode) << " trial " << trial;
    }
  }
}

TEST(HandEyeCalibration, RotationsAboutOneAxisAreDegenerate) {
  const CameraConfig cfg = sim_config();
  const CheckerBoard board{9, 6, 10.0};
  SimBoardScene scene(cfg, board);
  // Eye in hand, the flange only turning about its own z (a typical "spin the tool" set).
  const cv::Matx44d X = make_transform(euler_to_rotation(0, 0, 90), {40, -20, 90});
  const cv::Matx44d Y = make_transform(euler_to_rotation(180, 0, 0), {450, 0, 0});
  HandEyeCalibration cal(HandEyeMode::eye_in_hand, cfg.camera, board);
  for (int i = 0; i < 8; ++i) {
    const cv::Matx44d F = make_transform(euler_to_rotation(180, 0, -30 + 8.0 * i), {480, 30, 420 + 5.0 * i});
    const cv::Matx44d Tcb = X.inv() * F.inv() * Y;
    ASSERT_TRUE(cal.add_corners(scene.project_corners(Tcb), F).accepted);
  }
  try {
    cal.compute();
    FAIL() << "degenerate motion accepted";
  } catch (const CalibrationError& e) {
    EXPECT_NE(std::string(e.what()).find("degenerate motion"), std::string::npos) << e.what();
  }
  // Translations only: no rotation at all.
  HandEyeCalibration shifted(HandEyeMode::eye_in_hand, cfg.camera, board);
  for (int i = 0; i < 8; ++i) {
    const cv::Matx44d F = make_transform(euler_to_rotation(180, 0, 0), {480 + 4.0 * i, 30 - 3.0 * i, 420 + 5.0 * i});
    ASSERT_TRUE(shifted.add_corners(scene.project_corners(X.inv() * F.inv() * Y), F).accepted);
  }
  try {
    shifted.compute();
    FAIL() << "translation-only motion accepted";
  } catch (const CalibrationError& e) {
    EXPECT_NE(std::string(e.what()).find("barely rotate"), std::string::npos) << e.what();
  }
}

TEST(HandEyeCalibration, TooFewViewsAndMissingBoardAreClearErrors) {
  const CameraConfig cfg = sim_config();
  const CheckerBoard board{9, 6, 10.0};
  SimBoardScene scene(cfg, board);
  std::mt19937 rng(4);
  const SimHandEyeCell cell = make_sim_hand_eye_cell(scene, HandEyeMode::eye_in_hand, 3, cfg.working_distance_mm, rng);
  HandEyeCalibration cal(HandEyeMode::eye_in_hand, cfg.camera, board);
  for (const auto& v : cell.views) cal.add_corners(scene.project_corners(v.T_camera_board), v.flange.matrix());
  const ViewReport blank = cal.add_view(cv::Mat1b(480, 640, uint8_t{90}), cell.views[0].flange, "blank");
  EXPECT_FALSE(blank.accepted);
  EXPECT_NE(blank.reason.find("not found"), std::string::npos) << blank.reason;
  const ViewReport wrong_size = cal.add_view(cv::Mat1b(100, 100, uint8_t{90}), cell.views[0].flange, "small");
  EXPECT_FALSE(wrong_size.accepted);
  EXPECT_EQ(cal.view_count(), 3u);
  try {
    cal.compute();
    FAIL() << "3 views accepted";
  } catch (const CalibrationError& e) {
    EXPECT_NE(std::string(e.what()).find("too few views"), std::string::npos) << e.what();
  }
  EXPECT_THROW(HandEyeCalibration(HandEyeMode::eye_in_hand, cfg.camera, CheckerBoard{8, 6, 10}), CalibrationError);
}
