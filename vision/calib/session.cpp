#include "vision/calib/session.hpp"

namespace mfcd::vision::calib {

CalibrationSession::CalibrationSession(Kind kind, std::filesystem::path file, CameraConfig base)
    : kind_(kind), file_(std::move(file)), base_(std::move(base)) {}

CalibrationSession CalibrationSession::intrinsics(const std::filesystem::path& camera_file, const CheckerBoard& board,
                                                  const IntrinsicsOptions& options) {
  CalibrationSession s(Kind::intrinsics, camera_file, load_camera_config(camera_file));
  s.intrinsics_ = std::make_unique<IntrinsicsCalibration>(board, options);
  return s;
}

CalibrationSession CalibrationSession::hand_eye(const std::filesystem::path& camera_file, HandEyeMode mode,
                                                const CheckerBoard& board, const HandEyeOptions& options) {
  CalibrationSession s(Kind::hand_eye, camera_file, load_camera_config(camera_file));
  s.hand_eye_ = std::make_unique<HandEyeCalibration>(mode, s.base_.camera, board, options);
  return s;
}

ViewReport CalibrationSession::add_view(const cv::Mat& image, const std::optional<RobotPose>& flange,
                                        const std::string& label) {
  pending_.reset();  // a new view invalidates what was computed
  if (kind_ == Kind::intrinsics) return intrinsics_->add_view(image, label);
  if (!flange) {
    ViewReport r;
    r.label = label;
    r.reason = "hand-eye view without a robot flange pose";
    return r;
  }
  return hand_eye_->add_view(image, *flange, label);
}

size_t CalibrationSession::view_count() const {
  return kind_ == Kind::intrinsics ? intrinsics_->view_count() : hand_eye_->view_count();
}

std::string CalibrationSession::compute() {
  pending_.reset();
  if (kind_ == Kind::intrinsics) {
    intrinsics_result_ = intrinsics_->compute();
    pending_ = with_intrinsics(base_, *intrinsics_result_);
    return intrinsics_result_->summary();
  }
  hand_eye_result_ = hand_eye_->compute();
  pending_ = with_hand_eye(base_, *hand_eye_result_);
  return hand_eye_result_->summary();
}

const CameraConfig& CalibrationSession::pending() const {
  if (!pending_) throw CalibrationError(file_.string() + ": no calibration computed yet");
  return *pending_;
}

HandEyeCheck CalibrationSession::check(const cv::Mat& image, const RobotPose& flange) const {
  if (kind_ != Kind::hand_eye || !hand_eye_result_)
    throw CalibrationError("check: needs a computed hand-eye calibration");
  return hand_eye_->check(*hand_eye_result_, image, flange.matrix());
}

void CalibrationSession::apply() {
  CalibrationStore(file_).apply(pending());
  base_ = *pending_;
}

void CalibrationSession::rollback(const std::filesystem::path& camera_file) {
  CalibrationStore(camera_file).rollback();
}

}  // namespace mfcd::vision::calib
