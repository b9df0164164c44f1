#pragma once
// Imports a camera calibration made with another tool into the project's camera config:
//   - the YAML that OpenCV's calibration samples write (samples/cpp/calibration.cpp and
//     tutorial_camera_calibration: %YAML:1.0, !!opencv-matrix camera_matrix and
//     distortion_coefficients, image_width/image_height; also the capitalised keys of the
//     tutorial's OpenCV 2.x output, Camera_Matrix ...);
//   - a ROS camera_info YAML (camera_calibration_parsers, cameracalibrator.py's ost.yaml:
//     image_width/image_height, camera_matrix and distortion_coefficients as {rows, cols, data},
//     distortion_model).
// Such files hold the intrinsics only; the MFC keys (working distance, flash ring) come from
// options, an existing camera file, or the defaults of CameraConfig (docs/calibration.md,
// "Using a calibration from OpenCV or ROS").

#include "vision/camera/camera.hpp"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace mfcd::vision::calib {

enum class ForeignFormat { opencv, ros };
// "OpenCV calibration sample" / "ROS camera_info".
const char* to_string(ForeignFormat format);

// What a foreign calibration file gave. Pixel coordinates are the same in OpenCV, ROS and this
// project (the centre of pixel (0, 0) is at (0, 0)), so K and the coefficients are taken as they are.
struct ForeignCalibration {
  ForeignFormat format = ForeignFormat::opencv;
  PinholeCamera camera;                  // image size, K, distortion in OpenCV order (k1 k2 p1 p2 [k3 ...])
  std::string distortion_model;          // "plumb_bob", "rational_polynomial", or "OpenCV, N coefficients"
  std::vector<std::string> keys_read;    // top-level keys the intrinsics came from, in file order
  std::vector<std::string> keys_unused;  // the other top-level keys (board, extrinsics, R, P, ...)
  std::vector<std::string> notes;        // what the file said besides (its RMS error, camera name, ...)
};

// Reads and checks `file`; the format is detected from its keys (a ROS file has distortion_model,
// camera_name, rectification_matrix or projection_matrix; an OpenCV one has camera_matrix without
// them). Throws CalibrationError "<file>[:<line>]: key '<key>': <why>" for a file that is not a
// usable pinhole calibration: camera_matrix missing, not 3x3 or not [fx s cx; 0 fy cy; 0 0 1];
// fx or fy not finite and positive; image size missing or outside 1..20000; a coefficient count
// the distortion model does not have; a fisheye (equidistant) model; also XML, unparsable YAML,
// and a file that already is a camera file of this project.
ForeignCalibration read_foreign_calibration(const std::filesystem::path& file);

// The MFC keys a foreign file lacks. Each one not given comes from `base_camera_file` when set
// (its working distance and flashes; its hand_eye section is kept too), else from the defaults
// of CameraConfig / FlashRing::Ring: working distance 300 mm; a regular ring of radius 40 mm in
// the lens plane (plane_z 0 mm), LED 0 at 0 degrees, 45 degrees between LEDs.
struct MfcKeyOptions {
  std::optional<double> working_distance_mm;  // (0, 100000]
  std::optional<double> ring_radius_mm;       // (0, 1000]
  std::optional<double> first_angle_deg;      // finite
  std::optional<double> step_deg;             // finite
  std::optional<double> plane_z_mm;           // finite, below the working distance
  std::filesystem::path base_camera_file;     // empty: no base
};

// Where one MFC key's value came from.
struct MfcKeySource {
  enum class From { option, base, default_value };
  std::string key;  // "working_distance_mm", "flashes.ring_radius_mm", ... or "flashes.positions_mm"
  From from = From::default_value;
  std::string value;  // as printed, with its unit
};

struct CalibrationImport {
  ForeignCalibration source;
  CameraConfig config;  // validated (validate_camera_config)
  std::vector<MfcKeySource> mfc_keys;
  std::filesystem::path base_camera_file;  // MfcKeyOptions::base_camera_file
  // The keys of mfc_keys that took their default, in order.
  std::vector<std::string> defaults_used() const;
  // What was read, what was not used, and where each MFC key came from; several lines.
  std::string summary(const std::filesystem::path& file) const;
};

// read_foreign_calibration(file) plus the MFC keys. Throws CalibrationError for a refused file
// or an option out of its range (naming the camera key), std::runtime_error for an unreadable
// base camera file.
CalibrationImport import_calibration(const std::filesystem::path& file, const MfcKeyOptions& options = {});

}  // namespace mfcd::vision::calib
