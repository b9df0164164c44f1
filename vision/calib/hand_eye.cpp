#include "vision/calib/hand_eye.hpp"

#include <ceres/ceres.h>
#include <ceres/rotation.h>
#include <opencv2/calib3d.hpp>

#include <cmath>
#include <sstream>

namespace mfcd::vision::calib {

namespace {

// One corner of one view: its pixel predicted through Y (board), the robot pose and X.
// G = T_flange_base (eye in hand) or T_base_flange (eye to hand) is known; the camera
// sees p_camera = X^-1 * G * Y * p_board.
struct CornerCost {
  double G[12];
  double obj[3];
  double u, v, fx, fy, cx, cy;

  template <typename T>
  bool operator()(const T* x, const T* y, T* residual) const {
    const T p[3] = {T(obj[0]), T(obj[1]), T(obj[2])};
    T q[3];
    ceres::AngleAxisRotatePoint(y, p, q);
    for (int k = 0; k < 3; ++k) q[k] += y[3 + k];
    T d[3];
    for (int k = 0; k < 3; ++k)
      d[k] = G[4 * k] * q[0] + G[4 * k + 1] * q[1] + G[4 * k + 2] * q[2] + G[4 * k + 3] - x[3 + k];
    const T neg[3] = {-x[0], -x[1], -x[2]};
    T c[3];
    ceres::AngleAxisRotatePoint(neg, d, c);
    residual[0] = T(fx) * c[0] / c[2] + T(cx) - T(u);
    residual[1] = T(fy) * c[1] / c[2] + T(cy) - T(v);
    return true;
  }
};

void to_params(const cv::Matx44d& T, double* p) {
  const cv::Vec3d r = rotation_vector(rotation_of(T));
  for (int k = 0; k < 3; ++k) {
    p[k] = r[k];
    p[3 + k] = T(k, 3);
  }
}

cv::Matx44d from_params(const double* p) {
  return make_transform(rotation_from_vector({p[0], p[1], p[2]}), {p[3], p[4], p[5]});
}

bool is_rigid(const cv::Matx44d& T) {
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c)
      if (!std::isfinite(T(r, c))) return false;
  const cv::Matx33d R = rotation_of(T);
  return cv::norm(R.t() * R - cv::Matx33d::eye(), cv::NORM_INF) < 1e-6 && cv::determinant(R) > 0;
}

std::string describe_transform(const cv::Matx44d& T) {
  const RobotPose p = RobotPose::from_matrix(T);
  char buf[160];
  std::snprintf(buf, sizeof buf, "x %.3f y %.3f z %.3f mm, rx %.4f ry %.4f rz %.4f deg", p.x_mm, p.y_mm, p.z_mm,
                p.rx_deg, p.ry_deg, p.rz_deg);
  return buf;
}

}  // namespace

const char* to_string(HandEyeMode mode) { return mode == HandEyeMode::eye_in_hand ? "eye_in_hand" : "eye_to_hand"; }

HandEyeMode parse_hand_eye_mode(const std::string& text) {
  if (text == "eye-in-hand" || text == "eye_in_hand") return HandEyeMode::eye_in_hand;
  if (text == "eye-to-hand" || text == "eye_to_hand") return HandEyeMode::eye_to_hand;
  throw CalibrationError("hand-eye mode '" + text + "': expected eye-in-hand or eye-to-hand");
}

HandEyeCalibration::HandEyeCalibration(HandEyeMode mode, const PinholeCamera& camera, const CheckerBoard& board,
                                       const HandEyeOptions& options)
    : mode_(mode), camera_(camera), board_(board), options_(options) {
  board_.validate();
  if ((board_.columns + board_.rows) % 2 == 0)
    throw CalibrationError("board " + std::to_string(board_.columns) + "x" + std::to_string(board_.rows) +
                           ": hand-eye needs one even and one odd count of inner corners (e.g. 9x6) so that the "
                           "board's orientation is unambiguous");
  if (options_.min_views < 3) throw CalibrationError("hand-eye: min_views must be at least 3");
}

std::vector<cv::Point2f> HandEyeCalibration::undistort(const std::vector<cv::Point2f>& corners) const {
  std::vector<cv::Point2f> out;
  cv::undistortPoints(corners, out, cv::Mat(camera_.K), cv::Mat(camera_.distortion), cv::noArray(), cv::Mat(camera_.K));
  return out;
}

bool HandEyeCalibration::solve_pnp(const std::vector<cv::Point2f>& undistorted, cv::Matx44d& T) const {
  cv::Mat rvec, tvec;
  const std::vector<cv::Point3f> object = board_.object_points();
  if (!cv::solvePnP(object, undistorted, cv::Mat(camera_.K), cv::noArray(), rvec, tvec, false, cv::SOLVEPNP_IPPE))
    return false;
  cv::solvePnPRefineLM(object, undistorted, cv::Mat(camera_.K), cv::noArray(), rvec, tvec);
  T = make_transform(rotation_from_vector(cv::Vec3d(rvec)), cv::Vec3d(tvec));
  return is_rigid(T) && T(2, 3) > 0;
}

ViewReport HandEyeCalibration::add_view(const cv::Mat& image, const RobotPose& flange, const std::string& label) {
  return add_view(image, flange.matrix(), label);
}

ViewReport HandEyeCalibration::add_view(const cv::Mat& image, const cv::Matx44d& T_base_flange,
                                        const std::string& label) {
  ViewReport r;
  r.label = label;
  if (image.size() != camera_.image_size) {
    r.reason = "image size " + std::to_string(image.cols) + "x" + std::to_string(image.rows) +
               " differs from the camera's " + std::to_string(camera_.image_size.width) + "x" +
               std::to_string(camera_.image_size.height);
    return r;
  }
  const BoardDetection d = detect_board(image, board_);
  if (!d.found) {
    r.reason = d.reason;
    return r;
  }
  return add_corners(d.corners, T_base_flange, label);
}

ViewReport HandEyeCalibration::add_corners(const std::vector<cv::Point2f>& corners, const cv::Matx44d& T_base_flange,
                                           const std::string& label) {
  ViewReport r;
  r.label = label;
  if (static_cast<int>(corners.size()) != board_.corner_count()) {
    r.reason = "expected " + std::to_string(board_.corner_count()) + " corners, got " + std::to_string(corners.size());
    return r;
  }
  if (!is_rigid(T_base_flange)) {
    r.reason = "robot pose is not a rigid transform";
    return r;
  }
  View v;
  v.label = label.empty() ? "view " + std::to_string(views_.size()) : label;
  v.corners = undistort(corners);
  v.T_base_flange = T_base_flange;
  if (!solve_pnp(v.corners, v.T_camera_board)) {
    r.reason = "board pose could not be estimated (PnP failed)";
    return r;
  }
  views_.push_back(std::move(v));
  r.accepted = true;
  r.index = static_cast<int>(views_.size()) - 1;
  r.corners = corners;
  return r;
}

double HandEyeCalibration::check_motion_spread() const {
  // Rotation axes of the relative flange motions between every pair of views.
  std::vector<std::pair<double, cv::Vec3d>> axes;  // (angle deg, unit axis)
  for (size_t i = 0; i < views_.size(); ++i)
    for (size_t j = i + 1; j < views_.size(); ++j) {
      const cv::Vec3d w =
          rotation_vector(rotation_of(inverse_transform(views_[i].T_base_flange) * views_[j].T_base_flange));
      const double a = cv::norm(w) * 180 / CV_PI;
      if (a >= options_.min_rotation_deg) axes.emplace_back(a, w / cv::norm(w));
    }
  if (axes.size() < 2)
    throw CalibrationError("hand-eye: degenerate motion: the robot poses barely rotate (need rotations of at least " +
                           std::to_string(options_.min_rotation_deg) + " deg between views, about different axes)");
  size_t ref = 0;
  for (size_t k = 1; k < axes.size(); ++k)
    if (axes[k].first > axes[ref].first) ref = k;
  double spread = 0;
  for (const auto& [a, axis] : axes) {
    const double c = std::min(1.0, std::abs(axis.dot(axes[ref].second)));
    spread = std::max(spread, std::acos(c) * 180 / CV_PI);
  }
  if (spread < options_.min_axis_spread_deg) {
    const cv::Vec3d& ax = axes[ref].second;
    char buf[256];
    std::snprintf(buf, sizeof buf,
                  "hand-eye: degenerate motion: all robot rotations are about one axis (flange frame ~ %.2f %.2f %.2f, "
                  "spread %.1f deg < %.1f deg); tilt the flange about at least two different axes",
                  ax[0], ax[1], ax[2], spread, options_.min_axis_spread_deg);
    throw CalibrationError(buf);
  }
  return spread;
}

cv::Matx44d HandEyeCalibration::camera_board(const cv::Matx44d& X, const cv::Matx44d& Y, const cv::Matx44d& F) const {
  return mode_ == HandEyeMode::eye_in_hand ? inverse_transform(X) * inverse_transform(F) * Y
                                           : inverse_transform(X) * F * Y;
}

cv::Matx44d HandEyeCalibration::average_board(const cv::Matx44d& X) const {
  cv::Matx33d Rsum = cv::Matx33d::zeros();
  cv::Vec3d tsum(0, 0, 0);
  for (const auto& v : views_) {
    const cv::Matx44d Y = mode_ == HandEyeMode::eye_in_hand ? v.T_base_flange * X * v.T_camera_board
                                                            : inverse_transform(v.T_base_flange) * X * v.T_camera_board;
    Rsum += rotation_of(Y);
    tsum += translation_of(Y);
  }
  return make_transform(nearest_rotation(Rsum), tsum / static_cast<double>(views_.size()));
}

HandEyeViewResidual HandEyeCalibration::residual(const View& v, const cv::Matx44d& X, const cv::Matx44d& Y) const {
  HandEyeViewResidual r;
  r.label = v.label;
  const cv::Matx44d P = camera_board(X, Y, v.T_base_flange);
  const auto object = board_.object_points();
  double e2 = 0, d2 = 0;
  for (size_t k = 0; k < object.size(); ++k) {
    const cv::Vec3d o(object[k].x, object[k].y, object[k].z);
    const cv::Vec3d pc = transform_point(P, o);
    const cv::Point2d q = camera_.project(pc);
    e2 += (q.x - v.corners[k].x) * (q.x - v.corners[k].x) + (q.y - v.corners[k].y) * (q.y - v.corners[k].y);
    const cv::Vec3d oc = transform_point(v.T_camera_board, o);
    d2 += (pc - oc).dot(pc - oc);
  }
  r.rms_px = std::sqrt(e2 / static_cast<double>(object.size()));
  r.position_mm = std::sqrt(d2 / static_cast<double>(object.size()));
  r.rotation_deg = rotation_angle_deg(rotation_of(P), rotation_of(v.T_camera_board));
  return r;
}

double HandEyeCalibration::reprojection_rms_px(const cv::Matx44d& X, const cv::Matx44d& Y) const {
  double s = 0;
  for (const auto& v : views_) {
    const double e = residual(v, X, Y).rms_px;
    s += e * e;
  }
  return views_.empty() ? 0.0 : std::sqrt(s / static_cast<double>(views_.size()));
}

cv::Matx44d HandEyeCalibration::predict_camera_board(const HandEyeResult& r, const cv::Matx44d& F) const {
  return camera_board(r.hand_eye, r.board, F);
}

HandEyeResult HandEyeCalibration::compute() const {
  const int n = static_cast<int>(views_.size());
  if (n < options_.min_views)
    throw CalibrationError("hand-eye: too few views with the board found: " + std::to_string(n) + ", need at least " +
                           std::to_string(options_.min_views));
  HandEyeResult result;
  result.mode = mode_;
  result.axis_spread_deg = check_motion_spread();

  std::vector<cv::Mat> Rg, tg, Rc, tc;
  for (const auto& v : views_) {
    const cv::Matx44d G = mode_ == HandEyeMode::eye_in_hand ? v.T_base_flange : inverse_transform(v.T_base_flange);
    Rg.emplace_back(cv::Mat(rotation_of(G), true));
    tg.emplace_back(cv::Mat(translation_of(G), true));
    Rc.emplace_back(cv::Mat(rotation_of(v.T_camera_board), true));
    tc.emplace_back(cv::Mat(translation_of(v.T_camera_board), true));
  }
  const std::pair<cv::HandEyeCalibrationMethod, const char*> methods[] = {
      {cv::CALIB_HAND_EYE_TSAI, "Tsai"},
      {cv::CALIB_HAND_EYE_PARK, "Park"},
      {cv::CALIB_HAND_EYE_HORAUD, "Horaud"},
      {cv::CALIB_HAND_EYE_ANDREFF, "Andreff"},
      {cv::CALIB_HAND_EYE_DANIILIDIS, "Daniilidis"}};
  cv::Matx44d bestX, bestY;
  double best = INFINITY;
  for (const auto& [method, name] : methods) {
    HandEyeMethodScore s;
    s.method = name;
    try {
      cv::Mat R, t;
      cv::calibrateHandEye(Rg, tg, Rc, tc, R, t, method);
      const cv::Matx44d X = make_transform(cv::Matx33d(R), cv::Vec3d(t));
      if (is_rigid(X)) {
        const cv::Matx44d Y = average_board(X);
        s.rms_px = reprojection_rms_px(X, Y);
        s.ok = std::isfinite(s.rms_px);
        if (s.ok && s.rms_px < best) {
          best = s.rms_px;
          bestX = X;
          bestY = Y;
          result.initial_method = name;
        }
      }
    } catch (const cv::Exception&) {
      s.ok = false;
    }
    result.methods.push_back(s);
  }
  if (!std::isfinite(best)) throw CalibrationError("hand-eye: no cv::calibrateHandEye method gave a solution");
  result.initial_rms_px = best;
  result.hand_eye = bestX;
  result.board = bestY;

  if (options_.refine) {
    double x[6], y[6];
    to_params(bestX, x);
    to_params(bestY, y);
    ceres::Problem problem;
    const auto object = board_.object_points();
    for (const auto& v : views_) {
      const cv::Matx44d G = mode_ == HandEyeMode::eye_in_hand ? inverse_transform(v.T_base_flange) : v.T_base_flange;
      for (size_t k = 0; k < object.size(); ++k) {
        auto* c = new CornerCost{};
        for (int i = 0; i < 12; ++i) c->G[i] = G(i / 4, i % 4);
        c->obj[0] = object[k].x;
        c->obj[1] = object[k].y;
        c->obj[2] = object[k].z;
        c->u = v.corners[k].x;
        c->v = v.corners[k].y;
        c->fx = camera_.fx();
        c->fy = camera_.fy();
        c->cx = camera_.cx();
        c->cy = camera_.cy();
        problem.AddResidualBlock(new ceres::AutoDiffCostFunction<CornerCost, 2, 6, 6>(c), nullptr, x, y);
      }
    }
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::DENSE_QR;
    so.max_num_iterations = 200;
    so.function_tolerance = 1e-14;
    so.parameter_tolerance = 1e-14;
    so.gradient_tolerance = 1e-14;
    so.num_threads = 1;
    ceres::Solver::Summary summary;
    ceres::Solve(so, &problem, &summary);
    const cv::Matx44d X = from_params(x), Y = from_params(y);
    const double rms = reprojection_rms_px(X, Y);
    // Keep the closed-form solution should the solver fail to improve on it.
    if (summary.IsSolutionUsable() && std::isfinite(rms) && rms <= best) {
      result.hand_eye = X;
      result.board = Y;
    }
  }
  double e2 = 0, d2 = 0, r2 = 0;
  for (const auto& v : views_) {
    result.views.push_back(residual(v, result.hand_eye, result.board));
    const auto& r = result.views.back();
    e2 += r.rms_px * r.rms_px;
    d2 += r.position_mm * r.position_mm;
    r2 += r.rotation_deg * r.rotation_deg;
  }
  result.rms_px = std::sqrt(e2 / n);
  result.position_rms_mm = std::sqrt(d2 / n);
  result.rotation_rms_deg = std::sqrt(r2 / n);
  return result;
}

HandEyeCheck HandEyeCalibration::check(const HandEyeResult& result, const cv::Mat& image, const cv::Matx44d& F) const {
  HandEyeCheck c;
  const BoardDetection d = detect_board(image, board_);
  if (!d.found) {
    c.reason = d.reason;
    return c;
  }
  View v;
  v.label = "check";
  v.corners = undistort(d.corners);
  v.T_base_flange = F;
  if (!solve_pnp(v.corners, v.T_camera_board)) {
    c.reason = "board pose could not be estimated (PnP failed)";
    return c;
  }
  c.board_found = true;
  const HandEyeViewResidual r = residual(v, result.hand_eye, result.board);
  c.position_error_mm = r.position_mm;
  c.rotation_error_deg = r.rotation_deg;
  c.reprojection_rms_px = r.rms_px;
  c.origin_error_mm =
      cv::norm(translation_of(camera_board(result.hand_eye, result.board, F)) - translation_of(v.T_camera_board));
  return c;
}

std::string HandEyeResult::summary() const {
  std::ostringstream o;
  o.setf(std::ios::fixed);
  o.precision(3);
  const bool in_hand = mode == HandEyeMode::eye_in_hand;
  o << "hand-eye (" << to_string(mode) << ") from " << views.size() << " views, rotation axes spread "
    << axis_spread_deg << " deg\n  cv::calibrateHandEye:";
  for (const auto& m : methods) {
    o << ' ' << m.method << ' ';
    if (m.ok)
      o << m.rms_px << " px";
    else
      o << "failed";
  }
  o << "\n  best " << initial_method << ": " << initial_rms_px << " px; after joint refinement: " << rms_px << " px, "
    << position_rms_mm << " mm, " << rotation_rms_deg << " deg RMS\n"
    << "  " << (in_hand ? "T_flange_camera" : "T_base_camera") << ": " << describe_transform(hand_eye) << '\n'
    << "  " << (in_hand ? "T_base_board" : "T_flange_board") << ": " << describe_transform(board) << '\n';
  for (const auto& v : views)
    o << "  " << v.label << ": " << v.rms_px << " px, " << v.position_mm << " mm, " << v.rotation_deg << " deg\n";
  return o.str();
}

std::string HandEyeCheck::summary() const {
  if (!board_found) return "check: " + reason + "\n";
  std::ostringstream o;
  o.setf(std::ios::fixed);
  o.precision(3);
  o << "check: predicted vs observed board: " << position_error_mm << " mm RMS over the corners (origin "
    << origin_error_mm << " mm), " << rotation_error_deg << " deg, " << reprojection_rms_px << " px\n";
  return o.str();
}

CameraConfig with_hand_eye(CameraConfig config, const HandEyeResult& result) {
  HandEye h;
  h.mode = result.mode;
  h.camera_pose = result.hand_eye;
  h.reprojection_rms_px = result.rms_px;
  h.residual_rms_mm = result.position_rms_mm;
  h.views = static_cast<int>(result.views.size());
  config.hand_eye = h;
  return config;
}

}  // namespace mfcd::vision::calib
