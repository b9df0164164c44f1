#pragma once
// Hand-eye calibration: where the camera is relative to the robot, from views of a
// checkerboard taken at known robot flange poses.
//
//   eye_in_hand: camera on the flange, board fixed in the cell. Unknowns X = T_flange_camera
//                and Y = T_base_board;  T_base_flange_i * X * T_camera_board_i = Y.
//   eye_to_hand: camera fixed in the cell, board on the flange. Unknowns X = T_base_camera
//                and Y = T_flange_board; X * T_camera_board_i = T_base_flange_i * Y.
//
// compute() solves with cv::calibrateHandEye (Tsai, Park, Horaud, Andreff, Daniilidis; the
// one with the smallest corner reprojection error wins), then refines X and Y jointly with
// Ceres by minimising the reprojection error of every corner in every view.
//
// Session use (mfcd-ctl calibrate hand-eye, mfc-calibrate hand-eye):
//   HandEyeCalibration s(HandEyeMode::eye_in_hand, config.camera, board);
//   for each view: s.add_view(image, RobotPose{x, y, z, rx, ry, rz}, label);
//   HandEyeResult r = s.compute();          // throws CalibrationError
//   s.check(r, new_image, new_pose);        // optional: predicted vs observed board pose
//   on confirmation: CalibrationStore::apply(with_hand_eye(config, r)).

#include "vision/calib/board.hpp"
#include "vision/calib/intrinsics.hpp"
#include "vision/camera/camera.hpp"

#include <string>
#include <vector>

namespace mfcd::vision::calib {

using HandEyeMode = HandEye::Mode;
const char* to_string(HandEyeMode mode);
HandEyeMode parse_hand_eye_mode(const std::string& text);  // "eye-in-hand" / "eye_in_hand" / ...

struct HandEyeOptions {
  int min_views = 6;
  // Relative robot rotations smaller than this carry no information on the rotation axis.
  double min_rotation_deg = 5.0;
  // The rotation axes of the relative motions must spread by at least this angle, else the
  // motion is degenerate (the rotation about that axis leaves X's translation undetermined).
  double min_axis_spread_deg = 15.0;
  bool refine = true;  // Ceres joint refinement
};

struct HandEyeViewResidual {
  std::string label;
  double rms_px = 0;        // corner reprojection error through X, Y and the robot pose
  double position_mm = 0;   // RMS 3-D distance predicted vs observed (PnP) corners, camera frame
  double rotation_deg = 0;  // predicted vs observed board orientation
};

struct HandEyeMethodScore {
  std::string method;  // "Tsai", "Park", ...
  double rms_px = 0;   // with Y averaged over the views
  bool ok = false;
};

struct HandEyeResult {
  HandEyeMode mode = HandEyeMode::eye_in_hand;
  cv::Matx44d hand_eye = cv::Matx44d::eye();  // X: T_flange_camera or T_base_camera
  cv::Matx44d board = cv::Matx44d::eye();     // Y: T_base_board or T_flange_board
  std::vector<HandEyeMethodScore> methods;
  std::string initial_method;
  double initial_rms_px = 0;  // best cv::calibrateHandEye solution
  double rms_px = 0;          // final (after refinement when enabled)
  double position_rms_mm = 0;
  double rotation_rms_deg = 0;
  std::vector<HandEyeViewResidual> views;
  double axis_spread_deg = 0;  // of the relative robot rotations
  std::string summary() const;
};

// The board seen in a new view compared with where X, Y and the robot pose put it.
struct HandEyeCheck {
  bool board_found = false;
  std::string reason;
  double position_error_mm = 0;  // RMS over the corners, camera frame
  double origin_error_mm = 0;    // board origin
  double rotation_error_deg = 0;
  double reprojection_rms_px = 0;
  std::string summary() const;
};

class HandEyeCalibration {
 public:
  // `camera`: the calibrated intrinsics (corners are undistorted with them before use).
  HandEyeCalibration(HandEyeMode mode, const PinholeCamera& camera, const CheckerBoard& board,
                     const HandEyeOptions& options = {});

  // T_base_flange: the robot flange pose when the image was taken.
  ViewReport add_view(const cv::Mat& image, const cv::Matx44d& T_base_flange, const std::string& label = {});
  ViewReport add_view(const cv::Mat& image, const RobotPose& flange, const std::string& label = {});
  ViewReport add_corners(const std::vector<cv::Point2f>& corners, const cv::Matx44d& T_base_flange,
                         const std::string& label = {});
  size_t view_count() const { return views_.size(); }

  // Throws CalibrationError: too few views, degenerate motion, no method converged.
  HandEyeResult compute() const;
  // Reprojection RMS of the given X, Y over the views (the plain, per-corner computation the
  // refinement minimises; used for method scoring and reported figures).
  double reprojection_rms_px(const cv::Matx44d& hand_eye, const cv::Matx44d& board) const;
  // The board pose in the camera frame predicted by X, Y and a flange pose.
  cv::Matx44d predict_camera_board(const HandEyeResult& result, const cv::Matx44d& T_base_flange) const;
  HandEyeCheck check(const HandEyeResult& result, const cv::Mat& image, const cv::Matx44d& T_base_flange) const;
  // Rotation spread of the relative motions between views (degrees); throws like compute()
  // when the motion is degenerate.
  double check_motion_spread() const;

 private:
  struct View {
    std::string label;
    std::vector<cv::Point2f> corners;  // undistorted pixel coordinates (ideal pinhole)
    cv::Matx44d T_base_flange;
    cv::Matx44d T_camera_board;  // from PnP
  };
  bool solve_pnp(const std::vector<cv::Point2f>& undistorted, cv::Matx44d& T_camera_board) const;
  std::vector<cv::Point2f> undistort(const std::vector<cv::Point2f>& corners) const;
  cv::Matx44d camera_board(const cv::Matx44d& X, const cv::Matx44d& Y, const cv::Matx44d& T_base_flange) const;
  cv::Matx44d average_board(const cv::Matx44d& X) const;
  HandEyeViewResidual residual(const View& v, const cv::Matx44d& X, const cv::Matx44d& Y) const;

  HandEyeMode mode_;
  PinholeCamera camera_;
  CheckerBoard board_;
  HandEyeOptions options_;
  std::vector<View> views_;
};

// `config` with the hand-eye section set from the result.
CameraConfig with_hand_eye(CameraConfig config, const HandEyeResult& result);

}  // namespace mfcd::vision::calib
