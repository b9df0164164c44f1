// The simulated plate is found with the corners where the board convention puts them, and
// the pose helpers agree with their definitions.
#include "vision/calib/board.hpp"
#include "vision/calib/sim_board.hpp"

#include <gtest/gtest.h>

#include <random>

using namespace mfcd::vision;
using namespace mfcd::vision::calib;

namespace {
CameraConfig sim_config() { return load_camera_config(MFC_SOURCE_DIR "/config/camera-sim.yaml"); }
}  // namespace

TEST(CalibBoard, RenderedPlateCornersMatchTheirProjectionsInBoardOrder) {
  const CameraConfig cfg = sim_config();
  const CheckerBoard board{9, 6, 10.0};
  SimBoardScene scene(cfg, board);
  std::mt19937 rng(7);
  const auto poses = random_board_views(scene, 6, cfg.working_distance_mm, rng);
  for (size_t i = 0; i < poses.size(); ++i) {
    const cv::Mat1b img = scene.render(poses[i], 100 + i);
    const BoardDetection d = detect_board(img, board);
    ASSERT_TRUE(d.found) << "view " << i << ": " << d.reason;
    const auto truth = scene.project_corners(poses[i]);
    double worst = 0, sum2 = 0;
    for (size_t k = 0; k < truth.size(); ++k) {
      const double e = cv::norm(d.corners[k] - truth[k]);
      worst = std::max(worst, e);
      sum2 += e * e;
    }
    // Sub-pixel corners on a noisy, aliased render: well under a pixel, and in the board's
    // canonical order (a flipped order would put corners several squares away).
    EXPECT_LT(worst, 1.0) << "view " << i;
    EXPECT_LT(std::sqrt(sum2 / truth.size()), 0.45) << "view " << i;
  }
}

TEST(CalibBoard, BlankImageIsNotABoard) {
  const cv::Mat1b blank(480, 640, uint8_t{128});
  const BoardDetection d = detect_board(blank, CheckerBoard{9, 6, 10});
  EXPECT_FALSE(d.found);
  EXPECT_NE(d.reason.find("not found"), std::string::npos) << d.reason;
  EXPECT_FALSE(detect_board(cv::Mat(), CheckerBoard{}).found);
}

TEST(CalibBoard, EulerConventionIsRzRyRx) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> a(-179, 179), b(-89, 89);
  for (int i = 0; i < 200; ++i) {
    const double rx = a(rng), ry = b(rng), rz = a(rng);
    const cv::Matx33d R = euler_to_rotation(rx, ry, rz);
    // Slow twin: rotate about fixed X, then fixed Y, then fixed Z, each by Rodrigues.
    const cv::Matx33d Rx = rotation_from_vector({rx * CV_PI / 180, 0, 0});
    const cv::Matx33d Ry = rotation_from_vector({0, ry * CV_PI / 180, 0});
    const cv::Matx33d Rz = rotation_from_vector({0, 0, rz * CV_PI / 180});
    EXPECT_LT(cv::norm(R - Rz * Ry * Rx, cv::NORM_INF), 1e-12);
    const cv::Vec3d e = rotation_to_euler(R);
    EXPECT_NEAR(e[0], rx, 1e-9);
    EXPECT_NEAR(e[1], ry, 1e-9);
    EXPECT_NEAR(e[2], rz, 1e-9);
    const RobotPose p{a(rng), a(rng), a(rng), rx, ry, rz};
    const RobotPose q = RobotPose::from_matrix(p.matrix());
    EXPECT_NEAR(q.x_mm, p.x_mm, 1e-9);
    EXPECT_NEAR(q.rz_deg, p.rz_deg, 1e-9);
    EXPECT_LT(cv::norm(inverse_transform(p.matrix()) * p.matrix() - cv::Matx44d::eye(), cv::NORM_INF), 1e-12);
  }
}

TEST(CalibBoard, BoardSizesAreParsedAndValidated) {
  EXPECT_EQ(parse_pattern_size("9x6"), cv::Size(9, 6));
  EXPECT_THROW(parse_pattern_size("9by6"), CalibrationError);
  EXPECT_THROW(parse_pattern_size("9x"), CalibrationError);
  EXPECT_THROW(parse_pattern_size("9x6x2"), CalibrationError);
  EXPECT_THROW((CheckerBoard{7, 7, 10}.validate()), CalibrationError);
  EXPECT_THROW((CheckerBoard{9, 6, -1}.validate()), CalibrationError);
}
