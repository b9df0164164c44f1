#pragma once
// One calibration as the daemon runs it (mfcd-ctl calibrate intrinsics|hand-eye): collect
// views, compute, show the figures, and write the camera file only when the operator
// confirms; the replaced file stays available for rollback.
//
//   auto s = CalibrationSession::intrinsics("/etc/mfcd/camera.yaml", board);
//   s.add_view(ambient_image);                      // per capture; ViewReport says why not
//   std::string figures = s.compute();              // throws CalibrationError, file untouched
//   ... operator confirms ...  s.apply();           // atomic write, old file -> .previous
//   CalibrationSession::rollback("/etc/mfcd/camera.yaml");
//
// For hand-eye every view needs the robot flange pose (from the command line or the PLC
// registers): s.add_view(image, RobotPose{x, y, z, rx, ry, rz}).

#include "vision/calib/hand_eye.hpp"
#include "vision/calib/intrinsics.hpp"
#include "vision/calib/store.hpp"

#include <filesystem>
#include <memory>
#include <optional>
#include <string>

namespace mfcd::vision::calib {

class CalibrationSession {
 public:
  enum class Kind { intrinsics, hand_eye };

  // The camera file must exist and load (flashes, working distance and, for hand-eye, the
  // intrinsics come from it). Throws std::runtime_error naming the file otherwise.
  static CalibrationSession intrinsics(const std::filesystem::path& camera_file, const CheckerBoard& board,
                                       const IntrinsicsOptions& options = {});
  static CalibrationSession hand_eye(const std::filesystem::path& camera_file, HandEyeMode mode,
                                     const CheckerBoard& board, const HandEyeOptions& options = {});

  Kind kind() const { return kind_; }
  // Hand-eye views need `flange`; intrinsics views ignore it. A hand-eye view without a
  // pose is rejected with that reason.
  ViewReport add_view(const cv::Mat& image, const std::optional<RobotPose>& flange = std::nullopt,
                      const std::string& label = {});
  size_t view_count() const;

  // Computes and keeps the result pending; returns the figures to show. Throws
  // CalibrationError (nothing pending, nothing written).
  std::string compute();
  bool has_pending() const { return pending_.has_value(); }
  const CameraConfig& pending() const;  // throws when nothing was computed
  const std::optional<IntrinsicsResult>& intrinsics_result() const { return intrinsics_result_; }
  const std::optional<HandEyeResult>& hand_eye_result() const { return hand_eye_result_; }
  // Hand-eye only: predicted vs observed board in a new view (after compute()).
  HandEyeCheck check(const cv::Mat& image, const RobotPose& flange) const;

  // Writes the pending configuration (atomically, keeping the previous file). Throws when
  // nothing is pending or the write fails (the file is then unchanged).
  void apply();
  static void rollback(const std::filesystem::path& camera_file);

 private:
  CalibrationSession(Kind kind, std::filesystem::path file, CameraConfig base);
  Kind kind_;
  std::filesystem::path file_;
  CameraConfig base_;
  std::unique_ptr<IntrinsicsCalibration> intrinsics_;
  std::unique_ptr<HandEyeCalibration> hand_eye_;
  std::optional<CameraConfig> pending_;
  std::optional<IntrinsicsResult> intrinsics_result_;
  std::optional<HandEyeResult> hand_eye_result_;
};

}  // namespace mfcd::vision::calib
