#include "vision/calib/intrinsics.hpp"

#include <opencv2/calib3d.hpp>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace mfcd::vision::calib {

IntrinsicsCalibration::IntrinsicsCalibration(const CheckerBoard& board, const IntrinsicsOptions& options)
    : board_(board), options_(options) {
  board_.validate();
  if (options_.min_views < 3) throw CalibrationError("intrinsics: min_views must be at least 3");
}

ViewReport IntrinsicsCalibration::add_view(const cv::Mat& image, const std::string& label) {
  const BoardDetection d = detect_board(image, board_);
  if (!d.found) {
    ViewReport r;
    r.label = label;
    r.reason = d.reason;
    return r;
  }
  return add_corners(d.corners, image.size(), label);
}

ViewReport IntrinsicsCalibration::add_corners(const std::vector<cv::Point2f>& corners, cv::Size image_size,
                                              const std::string& label) {
  ViewReport r;
  r.label = label;
  if (static_cast<int>(corners.size()) != board_.corner_count()) {
    r.reason = "expected " + std::to_string(board_.corner_count()) + " corners, got " + std::to_string(corners.size());
    return r;
  }
  if (!corners_.empty() && image_size != image_size_) {
    r.reason = "image size " + std::to_string(image_size.width) + "x" + std::to_string(image_size.height) +
               " differs from the first view's " + std::to_string(image_size_.width) + "x" +
               std::to_string(image_size_.height);
    return r;
  }
  image_size_ = image_size;
  corners_.push_back(corners);
  labels_.push_back(label.empty() ? "view " + std::to_string(corners_.size() - 1) : label);
  r.accepted = true;
  r.index = static_cast<int>(corners_.size()) - 1;
  r.corners = corners;
  return r;
}

IntrinsicsResult IntrinsicsCalibration::compute() const {
  const int n = static_cast<int>(corners_.size());
  if (n < options_.min_views)
    throw CalibrationError("intrinsics: too few views with the board found: " + std::to_string(n) + ", need at least " +
                           std::to_string(options_.min_views) + " (tilted in different directions)");
  int flags = 0;
  switch (options_.distortion) {
    case IntrinsicsOptions::Distortion::none:
      flags = cv::CALIB_FIX_K1 | cv::CALIB_FIX_K2 | cv::CALIB_FIX_K3 | cv::CALIB_ZERO_TANGENT_DIST;
      break;
    case IntrinsicsOptions::Distortion::radial:
      flags = cv::CALIB_FIX_K3 | cv::CALIB_ZERO_TANGENT_DIST;
      break;
    case IntrinsicsOptions::Distortion::radial_tangential:
      flags = cv::CALIB_FIX_K3;
      break;
    case IntrinsicsOptions::Distortion::full:
      flags = 0;
      break;
  }
  const std::vector<cv::Point3f> object = board_.object_points();

  std::vector<bool> rejected(static_cast<size_t>(n), false);
  std::vector<double> view_rms(static_cast<size_t>(n), 0.0);
  IntrinsicsResult result;
  for (int round = 0;; ++round) {
    std::vector<std::vector<cv::Point3f>> obj;
    std::vector<std::vector<cv::Point2f>> img;
    std::vector<int> used;
    for (int i = 0; i < n; ++i)
      if (!rejected[static_cast<size_t>(i)]) {
        obj.push_back(object);
        img.push_back(corners_[static_cast<size_t>(i)]);
        used.push_back(i);
      }
    if (static_cast<int>(used.size()) < options_.min_views)
      throw CalibrationError("intrinsics: only " + std::to_string(used.size()) +
                             " views left after rejecting those that do not fit, need " +
                             std::to_string(options_.min_views));
    cv::Mat K, dist, rvecs, tvecs, std_intr, std_extr, per_view;
    double rms = 0;
    try {
      rms = cv::calibrateCamera(obj, img, image_size_, K, dist, rvecs, tvecs, std_intr, std_extr, per_view, flags,
                                cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-12));
    } catch (const cv::Exception& e) {
      throw CalibrationError(std::string("intrinsics: calibrateCamera failed: ") + e.what());
    }
    if (!std::isfinite(rms) || !cv::checkRange(K) || !cv::checkRange(dist))
      throw CalibrationError("intrinsics: calibration did not converge (non-finite result); add more tilted views");
    for (size_t k = 0; k < used.size(); ++k)
      view_rms[static_cast<size_t>(used[k])] = per_view.at<double>(static_cast<int>(k));

    std::vector<double> errs(view_rms.size());
    for (size_t k = 0; k < used.size(); ++k) errs[k] = view_rms[static_cast<size_t>(used[k])];
    errs.resize(used.size());
    std::nth_element(errs.begin(), errs.begin() + static_cast<long>(errs.size() / 2), errs.end());
    const double limit = std::max(options_.reject_factor * errs[errs.size() / 2], options_.reject_floor_px);
    // Drop the worst offender only, then recalibrate: one bad view inflates the others' errors.
    int worst = -1;
    for (int i : used)
      if (view_rms[static_cast<size_t>(i)] > limit &&
          (worst < 0 || view_rms[static_cast<size_t>(i)] > view_rms[static_cast<size_t>(worst)]))
        worst = i;
    if (worst >= 0) {
      rejected[static_cast<size_t>(worst)] = true;
      continue;
    }
    result.camera.image_size = image_size_;
    result.camera.K = cv::Matx33d(K);
    result.camera.distortion.assign(dist.begin<double>(), dist.end<double>());
    if (result.camera.distortion.size() > 5) result.camera.distortion.resize(5);
    result.rms_px = rms;
    result.used_views = static_cast<int>(used.size());
    result.std_dev = {std_intr.at<double>(0), std_intr.at<double>(1), std_intr.at<double>(2), std_intr.at<double>(3)};
    break;
  }
  for (int i = 0; i < n; ++i)
    result.views.push_back(
        {labels_[static_cast<size_t>(i)], view_rms[static_cast<size_t>(i)], rejected[static_cast<size_t>(i)]});
  return result;
}

std::string IntrinsicsResult::summary() const {
  std::ostringstream o;
  o.setf(std::ios::fixed);
  o.precision(3);
  o << "intrinsics from " << used_views << " of " << views.size() << " views: RMS reprojection " << rms_px << " px\n"
    << "  fx " << camera.fx() << " +- " << std_dev[0] << "  fy " << camera.fy() << " +- " << std_dev[1] << "  cx "
    << camera.cx() << " +- " << std_dev[2] << "  cy " << camera.cy() << " +- " << std_dev[3] << " px\n  distortion";
  o.precision(5);
  for (double d : camera.distortion) o << ' ' << d;
  o << '\n';
  o.precision(3);
  for (const auto& v : views)
    o << "  " << v.label << ": " << v.rms_px << " px" << (v.rejected ? "  REJECTED (does not fit the others)" : "")
      << '\n';
  return o.str();
}

IntrinsicsOptions::Distortion parse_distortion_model(const std::string& text) {
  using D = IntrinsicsOptions::Distortion;
  if (text == "none") return D::none;
  if (text == "radial") return D::radial;
  if (text == "radial-tangential" || text == "radial_tangential") return D::radial_tangential;
  if (text == "full") return D::full;
  throw CalibrationError("distortion model '" + text + "': expected none, radial, radial-tangential or full");
}

CameraConfig with_intrinsics(CameraConfig config, const IntrinsicsResult& result) {
  config.camera = result.camera;
  return config;
}

}  // namespace mfcd::vision::calib
