#pragma once
// The calibration board (a checkerboard), finding it in an image with sub-pixel corners,
// and the rigid transforms and robot poses calibration works with.
//
// Conventions (docs/calibration.md): a transform T_a_b maps points of frame b into frame a,
// p_a = T_a_b * p_b, as a 4x4 homogeneous matrix in millimetres. Robot poses are given as
// the controller reports them: x, y, z in mm and rx, ry, rz in degrees with
// R = Rz(rz) * Ry(ry) * Rx(rx) (the convention of motion/euler.hpp).

#include <opencv2/core.hpp>

#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace mfcd::vision::calib {

// Every calibration failure (too few views, degenerate motion, ...) is reported with this.
class CalibrationError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A checkerboard with `columns` x `rows` inner corners (OpenCV's pattern size) and square
// side `square_mm`. Board frame: origin at the first inner corner, x along a row of
// `columns` corners, y along a column, z = x cross y pointing into the board (away from a
// camera that sees its printed side). The first corner is the one whose diagonal outer
// neighbour square is dark; with one even and one odd count of squares this fixes the
// board frame uniquely (docs/calibration.md).
struct CheckerBoard {
  int columns = 9;
  int rows = 6;
  double square_mm = 10.0;

  cv::Size pattern_size() const { return {columns, rows}; }
  int corner_count() const { return columns * rows; }
  // Corner k = r * columns + c at (c * square, r * square, 0).
  std::vector<cv::Point3f> object_points() const;
  // Throws CalibrationError naming the bad field.
  void validate() const;
  // "9x6 corners, 10 mm squares"
  std::string describe() const;
};

// Parses "9x6" (inner corners). Throws CalibrationError on anything else.
cv::Size parse_pattern_size(const std::string& text);

struct BoardDetection {
  bool found = false;
  std::vector<cv::Point2f> corners;  // sub-pixel, in board order (see CheckerBoard)
  std::string reason;                // why not found, when !found
};

// Finds the board in an 8-bit grey (or BGR) image and orders the corners canonically.
BoardDetection detect_board(const cv::Mat& image, const CheckerBoard& board);

// A robot flange pose in the base frame as the controller reports it.
struct RobotPose {
  double x_mm = 0, y_mm = 0, z_mm = 0;
  double rx_deg = 0, ry_deg = 0, rz_deg = 0;

  cv::Matx44d matrix() const;  // T_base_flange
  static RobotPose from_matrix(const cv::Matx44d& T);
};

// R = Rz(rz) * Ry(ry) * Rx(rx), angles in degrees.
cv::Matx33d euler_to_rotation(double rx_deg, double ry_deg, double rz_deg);
// Inverse of euler_to_rotation; rx, rz in (-180, 180], ry in [-90, 90].
cv::Vec3d rotation_to_euler(const cv::Matx33d& R);

cv::Matx44d make_transform(const cv::Matx33d& R, const cv::Vec3d& t);
cv::Matx33d rotation_of(const cv::Matx44d& T);
cv::Vec3d translation_of(const cv::Matx44d& T);
cv::Matx44d inverse_transform(const cv::Matx44d& T);
cv::Vec3d transform_point(const cv::Matx44d& T, const cv::Vec3d& p);
// Rodrigues rotation vector (radians) <-> rotation matrix.
cv::Matx33d rotation_from_vector(const cv::Vec3d& rvec);
cv::Vec3d rotation_vector(const cv::Matx33d& R);
// Angle of R_a^T R_b in degrees.
double rotation_angle_deg(const cv::Matx33d& Ra, const cv::Matx33d& Rb);
// Closest rotation to a 3x3 matrix (SVD), used to average rotations.
cv::Matx33d nearest_rotation(const cv::Matx33d& M);

}  // namespace mfcd::vision::calib
