#pragma once
// The simulated cell's calibration plate: a checkerboard plate (vision/render checker paint)
// on a larger white backing plate, rendered by MfcRenderer at chosen poses, and robot
// motions that show it to the camera from well-spread viewpoints for both hand-eye set-ups.

#include "vision/calib/board.hpp"
#include "vision/calib/hand_eye.hpp"
#include "vision/render/mfc_renderer.hpp"

#include <memory>
#include <random>
#include <vector>

namespace mfcd::vision::calib {

// The calibration plate as meshes in someone else's renderer (the daemon's simulated cell
// shows it among its own scene): the checker-painted plate and its white backing plate.
class SimCalibrationPlate {
 public:
  SimCalibrationPlate(MfcRenderer& renderer, const CheckerBoard& board);
  // The two scene parts that put the plate at T_camera_board (board frame as in CheckerBoard).
  std::vector<ScenePart> parts(const cv::Matx44d& T_camera_board) const;
  const CheckerBoard& board() const { return board_; }

 private:
  CheckerBoard board_;
  int plate_mesh_ = -1, backing_mesh_ = -1;
  cv::Matx44d T_board_plate_, T_board_backing_;
};

// True when every corner of the plate (with its white margin), plus `margin_px`, falls inside
// the image of `camera`, in front of it, seen from the printed side.
bool plate_fully_visible(const PinholeCamera& camera, const CheckerBoard& board, const cv::Matx44d& T_camera_board,
                         double margin_px = 12);

class SimBoardScene {
 public:
  // The renderer's ambient light is raised to an evenly lit room so the ambient image (no
  // flash, no shadows) serves as the calibration image; sensor noise stays on.
  SimBoardScene(const CameraConfig& config, const CheckerBoard& board);
  ~SimBoardScene();

  // The ambient image of the plate at T_camera_board (board frame as in CheckerBoard).
  cv::Mat1b render(const cv::Matx44d& T_camera_board, uint64_t noise_seed = 1);
  // Ideal (noise-free, exact) projections of the board's inner corners.
  std::vector<cv::Point2f> project_corners(const cv::Matx44d& T_camera_board) const;
  // True when every corner of the plate, plus a margin, falls inside the image in front of
  // the camera.
  bool fully_visible(const cv::Matx44d& T_camera_board, double margin_px = 12) const;

  const CheckerBoard& board() const { return board_; }
  const PinholeCamera& camera() const { return config_.camera; }

 private:
  CameraConfig config_;
  CheckerBoard board_;
  std::unique_ptr<MfcRenderer> renderer_;
  std::unique_ptr<SimCalibrationPlate> plate_;
  MfcRender out_;
};

// Board poses in the camera frame spread for intrinsics calibration: distances
// [near, far] x working distance, tilts up to `max_tilt_deg` about a random in-plane axis,
// any roll, anywhere in the image; all fully visible.
std::vector<cv::Matx44d> random_board_views(const SimBoardScene& scene, int count, double working_distance_mm,
                                            std::mt19937& rng, double max_tilt_deg = 40, double near = 0.8,
                                            double far = 1.25);

// A simulated robot cell with a true hand-eye transform.
struct SimHandEyeCell {
  HandEyeMode mode = HandEyeMode::eye_in_hand;
  // eye_in_hand: T_flange_camera and T_base_board; eye_to_hand: T_base_camera and T_flange_board.
  cv::Matx44d hand_eye_true;
  cv::Matx44d board_true;
  struct View {
    RobotPose flange;            // as the controller would report it (0.001 mm / deg steps)
    cv::Matx44d T_camera_board;  // what the camera sees (from the reported pose, exactly)
  };
  std::vector<View> views;
};

// The two directions of a simulated hand-eye cell with true X (hand_eye) and Y (board), see
// hand_eye.hpp: the board pose the camera sees at a flange pose, and the flange pose that
// shows the board at T_camera_board.
cv::Matx44d sim_camera_board(HandEyeMode mode, const cv::Matx44d& hand_eye, const cv::Matx44d& board,
                             const cv::Matx44d& T_base_flange);
cv::Matx44d sim_flange_pose(HandEyeMode mode, const cv::Matx44d& hand_eye, const cv::Matx44d& board,
                            const cv::Matx44d& T_camera_board);

// Board poses in the camera frame as random_board_views() draws them, from the camera and board
// alone (no renderer): for tests that drive a simulated cell elsewhere (mfcd's).
std::vector<cv::Matx44d> random_plate_views(const PinholeCamera& camera, const CheckerBoard& board, int count,
                                            double working_distance_mm, std::mt19937& rng, double max_tilt_deg = 40,
                                            double near = 0.8, double far = 1.25);

// Builds a cell with a fixed, plausible true transform and `count` robot poses that show
// the whole board from well-spread directions (rotation axes spread in 3-D).
SimHandEyeCell make_sim_hand_eye_cell(const SimBoardScene& scene, HandEyeMode mode, int count,
                                      double working_distance_mm, std::mt19937& rng);

}  // namespace mfcd::vision::calib
