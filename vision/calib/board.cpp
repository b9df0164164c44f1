#include "vision/calib/board.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace mfcd::vision::calib {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

float sample(const cv::Mat1b& img, cv::Point2f p) {
  cv::Mat patch;
  cv::getRectSubPix(img, {3, 3}, p, patch, CV_32F);
  return static_cast<float>(cv::mean(patch)[0]);
}

}  // namespace

std::vector<cv::Point3f> CheckerBoard::object_points() const {
  std::vector<cv::Point3f> pts;
  pts.reserve(static_cast<size_t>(corner_count()));
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < columns; ++c)
      pts.emplace_back(static_cast<float>(c * square_mm), static_cast<float>(r * square_mm), 0.f);
  return pts;
}

void CheckerBoard::validate() const {
  if (columns < 3 || rows < 3 || columns > 100 || rows > 100)
    throw CalibrationError("board: inner corners must be 3..100 per side, got " + std::to_string(columns) + "x" +
                           std::to_string(rows));
  if (columns == rows)
    throw CalibrationError("board: a square pattern (" + std::to_string(columns) + "x" + std::to_string(rows) +
                           ") has no defined orientation; use e.g. 9x6 inner corners");
  if (!(square_mm > 0) || square_mm > 1000)
    throw CalibrationError("board: square size must be in (0, 1000] mm, got " + std::to_string(square_mm));
}

std::string CheckerBoard::describe() const {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%dx%d inner corners, %.3g mm squares", columns, rows, square_mm);
  return buf;
}

cv::Size parse_pattern_size(const std::string& text) {
  // Digits 'x' digits, nothing else (std::regex trips GCC 12's -Wmaybe-uninitialized under ASan).
  const size_t x = text.find_first_of("xX");
  auto digits = [](const std::string& s) {
    return !s.empty() && s.size() <= 3 && s.find_first_not_of("0123456789") == std::string::npos;
  };
  if (x == std::string::npos || !digits(text.substr(0, x)) || !digits(text.substr(x + 1)))
    throw CalibrationError("board size '" + text + "': expected COLUMNSxROWS inner corners, e.g. 9x6");
  return {std::stoi(text.substr(0, x)), std::stoi(text.substr(x + 1))};
}

BoardDetection detect_board(const cv::Mat& image, const CheckerBoard& board) {
  BoardDetection d;
  if (image.empty()) {
    d.reason = "empty image";
    return d;
  }
  cv::Mat1b gray;
  if (image.type() == CV_8UC1)
    gray = image;
  else if (image.type() == CV_8UC3)
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  else {
    d.reason = "unsupported image type (expected 8-bit grey or BGR)";
    return d;
  }
  std::vector<cv::Point2f> c;
  const bool ok = cv::findChessboardCorners(gray, board.pattern_size(), c,
                                            cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE);
  if (!ok || static_cast<int>(c.size()) != board.corner_count()) {
    d.reason = "board " + std::to_string(board.columns) + "x" + std::to_string(board.rows) +
               " not found (all inner corners must be visible, with a light border round the squares)";
    return d;
  }
  const int C = board.columns, R = board.rows;
  auto at = [&](const std::vector<cv::Point2f>& v, int r, int col) { return v[static_cast<size_t>(r * C + col)]; };

  // Sub-pixel refinement with a window well inside one square.
  double spacing = 1e9;
  for (int r = 0; r < R; ++r)
    for (int col = 0; col + 1 < C; ++col) spacing = std::min(spacing, cv::norm(at(c, r, col + 1) - at(c, r, col)));
  for (int r = 0; r + 1 < R; ++r)
    for (int col = 0; col < C; ++col) spacing = std::min(spacing, cv::norm(at(c, r + 1, col) - at(c, r, col)));
  if (spacing < 6) {
    d.reason = "board too small in the image (corners " + std::to_string(spacing) + " px apart, need >= 6)";
    return d;
  }
  const int win = std::clamp(static_cast<int>(spacing * 0.35), 2, 11);
  cv::cornerSubPix(gray, c, {win, win}, {-1, -1},
                   cv::TermCriteria(cv::TermCriteria::EPS | cv::TermCriteria::COUNT, 100, 1e-4));

  // Canonical order: among the four re-orderings of the grid that keep rows as rows,
  // take the one seen from the printed side (board x right-ish, y down-ish: positive
  // image-plane cross product) whose first square is dark.
  std::vector<cv::Point2f> best;
  for (int flip_r = 0; flip_r < 2 && best.empty(); ++flip_r)
    for (int flip_c = 0; flip_c < 2 && best.empty(); ++flip_c) {
      std::vector<cv::Point2f> o(c.size());
      for (int r = 0; r < R; ++r)
        for (int col = 0; col < C; ++col)
          o[static_cast<size_t>(r * C + col)] = at(c, flip_r ? R - 1 - r : r, flip_c ? C - 1 - col : col);
      const cv::Point2f ex = at(o, 0, C - 1) - at(o, 0, 0), ey = at(o, R - 1, 0) - at(o, 0, 0);
      if (ex.x * ey.y - ex.y * ey.x <= 0) continue;
      const cv::Point2f first = (at(o, 0, 0) + at(o, 0, 1) + at(o, 1, 0) + at(o, 1, 1)) * 0.25f;
      const cv::Point2f second = (at(o, 0, 1) + at(o, 0, 2) + at(o, 1, 1) + at(o, 1, 2)) * 0.25f;
      if (sample(gray, first) < sample(gray, second)) best = std::move(o);
    }
  if (best.empty()) {
    d.reason = "board orientation undecided (squares too low in contrast)";
    return d;
  }
  d.found = true;
  d.corners = std::move(best);
  return d;
}

cv::Matx33d euler_to_rotation(double rx_deg, double ry_deg, double rz_deg) {
  const double a = rx_deg * kDeg, b = ry_deg * kDeg, g = rz_deg * kDeg;
  const cv::Matx33d Rx(1, 0, 0, 0, std::cos(a), -std::sin(a), 0, std::sin(a), std::cos(a));
  const cv::Matx33d Ry(std::cos(b), 0, std::sin(b), 0, 1, 0, -std::sin(b), 0, std::cos(b));
  const cv::Matx33d Rz(std::cos(g), -std::sin(g), 0, std::sin(g), std::cos(g), 0, 0, 0, 1);
  return Rz * Ry * Rx;
}

cv::Vec3d rotation_to_euler(const cv::Matx33d& R) {
  // R(2,0) = -sin(ry); R(2,1) = cos(ry) sin(rx); R(2,2) = cos(ry) cos(rx);
  // R(1,0) = sin(rz) cos(ry); R(0,0) = cos(rz) cos(ry).
  const double cy = std::hypot(R(2, 1), R(2, 2));
  double rx, ry = std::atan2(-R(2, 0), cy), rz;
  if (cy > 1e-9) {
    rx = std::atan2(R(2, 1), R(2, 2));
    rz = std::atan2(R(1, 0), R(0, 0));
  } else {  // gimbal lock: only rz -/+ rx is defined; report rx = 0
    rx = 0;
    rz = std::atan2(-R(0, 1), R(1, 1));
  }
  return {rx / kDeg, ry / kDeg, rz / kDeg};
}

cv::Matx44d RobotPose::matrix() const {
  return make_transform(euler_to_rotation(rx_deg, ry_deg, rz_deg), {x_mm, y_mm, z_mm});
}

RobotPose RobotPose::from_matrix(const cv::Matx44d& T) {
  const cv::Vec3d e = rotation_to_euler(rotation_of(T));
  return {T(0, 3), T(1, 3), T(2, 3), e[0], e[1], e[2]};
}

cv::Matx44d make_transform(const cv::Matx33d& R, const cv::Vec3d& t) {
  return {R(0, 0), R(0, 1), R(0, 2), t[0], R(1, 0), R(1, 1), R(1, 2), t[1],
          R(2, 0), R(2, 1), R(2, 2), t[2], 0,       0,       0,       1};
}

cv::Matx33d rotation_of(const cv::Matx44d& T) { return T.get_minor<3, 3>(0, 0); }
cv::Vec3d translation_of(const cv::Matx44d& T) { return {T(0, 3), T(1, 3), T(2, 3)}; }

cv::Matx44d inverse_transform(const cv::Matx44d& T) {
  const cv::Matx33d Rt = rotation_of(T).t();
  return make_transform(Rt, -(Rt * translation_of(T)));
}

cv::Vec3d transform_point(const cv::Matx44d& T, const cv::Vec3d& p) { return rotation_of(T) * p + translation_of(T); }

cv::Matx33d rotation_from_vector(const cv::Vec3d& rvec) {
  cv::Matx33d R;
  cv::Rodrigues(rvec, R);
  return R;
}

cv::Vec3d rotation_vector(const cv::Matx33d& R) {
  cv::Vec3d r;
  cv::Rodrigues(R, r);
  return r;
}

double rotation_angle_deg(const cv::Matx33d& Ra, const cv::Matx33d& Rb) {
  const cv::Matx33d D = Ra.t() * Rb;
  const double c = std::clamp((cv::trace(D) - 1.0) / 2.0, -1.0, 1.0);
  return std::acos(c) / kDeg;
}

cv::Matx33d nearest_rotation(const cv::Matx33d& M) {
  cv::Matx33d U, Vt;
  cv::Matx31d w;
  cv::SVD::compute(M, w, U, Vt);
  cv::Matx33d R = U * Vt;
  if (cv::determinant(R) < 0) R = U * cv::Matx33d::diag({1, 1, -1}) * Vt;
  return R;
}

}  // namespace mfcd::vision::calib
