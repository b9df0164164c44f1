#pragma once
// Pinhole camera + multi-flash (MFC) LED geometry, read from / written to OpenCV
// FileStorage YAML. Axes follow OpenCV: x right, y down, z forward (optical axis);
// all lengths in millimetres. docs/camera.md documents every YAML key.

#include <opencv2/core.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace mfcd::vision {

// Intrinsics of an ideal pinhole plus the lens distortion measured by calibration.
// Pixel coordinates are OpenCV's: the centre of pixel (0, 0) is at (0, 0).
struct PinholeCamera {
  cv::Size image_size{640, 480};
  cv::Matx33d K = cv::Matx33d::eye();
  // OpenCV order (k1, k2, p1, p2[, k3, ...]); the renderer simulates an ideal pinhole,
  // so real images are expected to be undistorted before matching.
  std::vector<double> distortion = {0, 0, 0, 0, 0};

  double fx() const { return K(0, 0); }
  double fy() const { return K(1, 1); }
  double cx() const { return K(0, 2); }
  double cy() const { return K(1, 2); }

  // Projects a camera-frame point (z > 0) to pixel coordinates (no distortion).
  cv::Point2d project(const cv::Vec3d& p) const;
  // The same camera restricted to a window of the image: renders of the window equal
  // the corresponding crop of a full-size render (used to render only around a part).
  PinholeCamera cropped(const cv::Rect& window) const;
};

// The ring of LEDs around the lens. Positions are in the camera frame (mm), in firing
// order: image i of an MFC frame set is lit by positions_mm[i] alone.
struct FlashRing {
  // How the positions were specified: a regular ring (radius/angles) or measured
  // positions listed one by one. Kept so that a written file reads back identically.
  struct Ring {
    double radius_mm = 40.0;
    double first_angle_deg = 0.0;  // angle of LED 0 from +x towards +y (image right, then down)
    double step_deg = 45.0;        // angle between consecutive LEDs in firing order
    double plane_z_mm = 0.0;       // z of the LED plane (0 = the lens' optical centre)
    int count = 8;
  };
  std::optional<Ring> ring;
  std::vector<cv::Vec3d> positions_mm;

  static FlashRing regular(const Ring& ring);
};

// Where the camera sits relative to the robot, from hand-eye calibration (vision/calib,
// docs/calibration.md). Transforms map points of the right-hand frame into the left-hand
// one (p_flange = T_flange_camera * p_camera), millimetres.
struct HandEye {
  enum class Mode { eye_in_hand, eye_to_hand };
  Mode mode = Mode::eye_in_hand;
  // eye_in_hand: camera in the robot flange frame (T_flange_camera);
  // eye_to_hand: camera in the robot base frame (T_base_camera).
  cv::Matx44d camera_pose = cv::Matx44d::eye();
  // The figures the calibration reported, kept with the result for the record.
  double reprojection_rms_px = 0.0;
  double residual_rms_mm = 0.0;
  int views = 0;
};

struct CameraConfig {
  PinholeCamera camera;
  FlashRing flashes = FlashRing::regular({});
  double working_distance_mm = 300.0;  // lens to the bin floor / parts, along z
  std::optional<HandEye> hand_eye;     // absent until a hand-eye calibration is applied
};

// Reads a camera YAML (as save_camera_config writes it; read with yaml-cpp). Throws
// std::runtime_error naming the file, the line (where the node has one) and the missing or
// malformed key; every count and matrix size is checked against its range before anything is
// allocated by it.
CameraConfig load_camera_config(const std::filesystem::path& file);
// Writes a camera YAML (whatever the extension) that load_camera_config reads back to an equal
// config.
void save_camera_config(const CameraConfig& config, const std::filesystem::path& file);
// Checks the values are physically sensible; throws std::runtime_error naming the key.
void validate_camera_config(const CameraConfig& config, const std::string& source = "camera config");

// Where a flash's shadows fall in the image. For an LED at L (camera frame), the shadow of
// a surface point P lies on the ray L -> P beyond P, whose image moves away from the LED's
// epipole e = K L (homogeneous). At pixel p = (u, v) the shadow direction is
// e_z * p - (e_x, e_y): for an LED in the lens plane (e_z = 0) it is -(fx Lx, fy Ly)
// everywhere, i.e. shadows fall away from the LED's side.
struct FlashEpipole {
  double ex = 0, ey = 0, ez = 0;
  cv::Vec2d shadow_direction(double u, double v) const { return {ez * u - ex, ez * v - ey}; }
};
FlashEpipole flash_epipole(const PinholeCamera& camera, const cv::Vec3d& led_mm);

}  // namespace mfcd::vision
