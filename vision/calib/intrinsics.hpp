#pragma once
// Camera intrinsics from checkerboard views: OpenCV calibrateCamera on sub-pixel corners,
// per-view reprojection errors and rejection of views that do not fit the others.
//
// Session use (mfcd-ctl calibrate intrinsics, mfc-calibrate intrinsics):
//   IntrinsicsCalibration s(board);
//   for each captured image: ViewReport v = s.add_view(image, label);  // v.accepted / v.reason
//   IntrinsicsResult r = s.compute();       // throws CalibrationError
//   print r.summary(); on confirmation CalibrationStore::apply(with_intrinsics(config, r)).

#include "vision/calib/board.hpp"
#include "vision/camera/camera.hpp"

#include <string>
#include <vector>

namespace mfcd::vision::calib {

// What add_view did with one image.
struct ViewReport {
  int index = -1;  // index among the accepted views, -1 when rejected
  bool accepted = false;
  std::string label;   // the caller's name for the view (file name, "view 3", ...)
  std::string reason;  // why it was rejected
  std::vector<cv::Point2f> corners;
};

struct IntrinsicsOptions {
  int min_views = 6;
  // Lens model. radial: k1, k2 (the default, for long
  // machine-vision lenses like the MFC's, where tangential terms trade off against the
  // principal point); radial_tangential: k1, k2, p1, p2;
  // full: k1, k2, p1, p2, k3 (wide angle); none: ideal pinhole (the simulated camera).
  enum class Distortion { none, radial, radial_tangential, full };
  Distortion distortion = Distortion::radial;
  // A view whose RMS reprojection error exceeds max(reject_factor x median, reject_floor_px)
  // is dropped and the calibration repeated without it.
  double reject_factor = 3.0;
  double reject_floor_px = 1.0;
};

struct IntrinsicsViewError {
  std::string label;
  double rms_px = 0;
  bool rejected = false;
};

struct IntrinsicsResult {
  PinholeCamera camera;
  double rms_px = 0;                       // over the views used
  std::vector<IntrinsicsViewError> views;  // every accepted view, in order
  int used_views = 0;
  cv::Vec4d std_dev{0, 0, 0, 0};  // 1-sigma of fx, fy, cx, cy (px)
  std::string summary() const;
};

class IntrinsicsCalibration {
 public:
  explicit IntrinsicsCalibration(const CheckerBoard& board, const IntrinsicsOptions& options = {});

  ViewReport add_view(const cv::Mat& image, const std::string& label = {});
  // Corners found elsewhere (board order); for tests and for replaying a session.
  ViewReport add_corners(const std::vector<cv::Point2f>& corners, cv::Size image_size, const std::string& label = {});
  size_t view_count() const { return corners_.size(); }
  const CheckerBoard& board() const { return board_; }

  // Throws CalibrationError: too few views, failure to converge, too few views left after
  // rejection, non-finite result.
  IntrinsicsResult compute() const;

 private:
  CheckerBoard board_;
  IntrinsicsOptions options_;
  cv::Size image_size_;
  std::vector<std::vector<cv::Point2f>> corners_;
  std::vector<std::string> labels_;
};

// "none", "radial", "radial-tangential", "full"; throws CalibrationError otherwise.
IntrinsicsOptions::Distortion parse_distortion_model(const std::string& text);

// `config` with its camera intrinsics replaced by the result (flashes etc. untouched).
CameraConfig with_intrinsics(CameraConfig config, const IntrinsicsResult& result);

}  // namespace mfcd::vision::calib
