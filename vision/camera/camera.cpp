#include "vision/camera/camera.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace mfcd::vision {

namespace {

[[noreturn]] void fail(const std::string& source, const std::string& key, const std::string& why) {
  throw std::runtime_error(source + ": key '" + key + "': " + why);
}

cv::FileNode required(const cv::FileNode& parent, const std::string& key, const std::string& source) {
  cv::FileNode n = parent[key];
  if (n.empty() || n.isNone()) fail(source, key, "missing");
  return n;
}

double read_number(const cv::FileNode& parent, const std::string& key, const std::string& source,
                   const std::string& shown_key) {
  cv::FileNode n = required(parent, key, source);
  if (!n.isReal() && !n.isInt()) fail(source, shown_key, "expected a number");
  return n.real();
}

int read_int(const cv::FileNode& parent, const std::string& key, const std::string& source,
             const std::string& shown_key) {
  cv::FileNode n = required(parent, key, source);
  if (!n.isInt()) fail(source, shown_key, "expected an integer");
  return static_cast<int>(n);
}

// The shape an !!opencv-matrix key must have, and how a refusal states it.
struct MatrixShape {
  int min_rows, max_rows, min_cols, max_cols;
  const char* expected;
};

// Reads an !!opencv-matrix after checking its rows, cols, dt and data length against `shape`:
// cv::read() sizes the matrix from rows x cols before it compares them with the data, so an
// unchecked "rows: 2000000000" would allocate gigabytes before any refusal.
cv::Mat read_matrix(const cv::FileNode& parent, const std::string& key, const std::string& source,
                    const std::string& shown_key, const MatrixShape& shape) {
  cv::FileNode n = required(parent, key, source);
  if (!n.isMap()) fail(source, shown_key, "expected an !!opencv-matrix");
  const cv::FileNode rows = n["rows"], cols = n["cols"], dt = n["dt"], data = n["data"];
  if (!rows.isInt() || !cols.isInt()) fail(source, shown_key, "expected integer 'rows' and 'cols'");
  const int r = static_cast<int>(rows), c = static_cast<int>(cols);
  if (r < shape.min_rows || r > shape.max_rows || c < shape.min_cols || c > shape.max_cols)
    fail(source, shown_key,
         "a " + std::to_string(r) + "x" + std::to_string(c) + " matrix, expected " + shape.expected);
  // One channel of a number type: u c w s i f d (OpenCV's type letters).
  const std::string type = dt.isString() ? static_cast<std::string>(dt) : std::string();
  if (type.size() != 1 || std::string("ucwsifd").find(type[0]) == std::string::npos)
    fail(source, shown_key, "expected 'dt' to be one number type (d, f, i, ...), got '" + type + "'");
  if (!data.isSeq() || data.size() != static_cast<size_t>(r) * static_cast<size_t>(c))
    fail(source, shown_key, "'data' must list rows x cols = " + std::to_string(r * c) + " numbers");
  cv::Mat m;
  try {
    n >> m;
  } catch (const cv::Exception& e) {
    fail(source, shown_key, std::string("malformed matrix: ") + e.what());
  }
  if (m.rows != r || m.cols != c || m.channels() != 1) fail(source, shown_key, "malformed matrix");
  m.convertTo(m, CV_64F);
  return m;
}

// The number of LEDs of an MFC (docs/camera.md): flashes.count and flashes.positions_mm rows.
constexpr int kLedCount = 8;

}  // namespace

cv::Point2d PinholeCamera::project(const cv::Vec3d& p) const {
  const cv::Vec3d h = K * p;
  return {h[0] / h[2], h[1] / h[2]};
}

PinholeCamera PinholeCamera::cropped(const cv::Rect& window) const {
  PinholeCamera c = *this;
  c.image_size = window.size();
  c.K(0, 2) -= window.x;
  c.K(1, 2) -= window.y;
  return c;
}

FlashRing FlashRing::regular(const Ring& ring) {
  FlashRing f;
  f.ring = ring;
  for (int i = 0; i < ring.count; ++i) {
    const double a = (ring.first_angle_deg + i * ring.step_deg) * std::numbers::pi / 180.0;
    f.positions_mm.emplace_back(ring.radius_mm * std::cos(a), ring.radius_mm * std::sin(a), ring.plane_z_mm);
  }
  return f;
}

FlashEpipole flash_epipole(const PinholeCamera& camera, const cv::Vec3d& led_mm) {
  const cv::Vec3d e = camera.K * led_mm;
  return {e[0], e[1], e[2]};
}

void validate_camera_config(const CameraConfig& c, const std::string& source) {
  const auto& cam = c.camera;
  if (cam.image_size.width <= 0 || cam.image_size.width > 20000) fail(source, "image_width", "must be in 1..20000");
  if (cam.image_size.height <= 0 || cam.image_size.height > 20000) fail(source, "image_height", "must be in 1..20000");
  if (!(cam.fx() > 0) || !(cam.fy() > 0)) fail(source, "camera_matrix", "fx and fy must be positive");
  if (cam.K(1, 0) != 0 || cam.K(2, 0) != 0 || cam.K(2, 1) != 0 || cam.K(2, 2) != 1)
    fail(source, "camera_matrix", "must be [fx s cx; 0 fy cy; 0 0 1]");
  for (int r = 0; r < 3; ++r)
    for (int col = 0; col < 3; ++col)
      if (!std::isfinite(cam.K(r, col))) fail(source, "camera_matrix", "non-finite entry");
  if (cam.distortion.size() < 4 || cam.distortion.size() > 14)
    fail(source, "distortion_coefficients", "expected 4 to 14 coefficients");
  if (!(c.working_distance_mm > 0) || c.working_distance_mm > 1e5)
    fail(source, "working_distance_mm", "must be in (0, 100000] mm");
  if (c.flashes.positions_mm.size() != 8)
    fail(source, c.flashes.ring ? "flashes.count" : "flashes.positions_mm",
         "an MFC has 8 LEDs, got " + std::to_string(c.flashes.positions_mm.size()));
  for (const auto& p : c.flashes.positions_mm) {
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
      fail(source, "flashes", "non-finite LED position");
    if (p[2] >= c.working_distance_mm) fail(source, "flashes", "LED behind the working distance");
  }
  if (c.hand_eye) {
    const cv::Matx44d& T = c.hand_eye->camera_pose;
    for (int r = 0; r < 4; ++r)
      for (int col = 0; col < 4; ++col)
        if (!std::isfinite(T(r, col))) fail(source, "hand_eye.camera_pose", "non-finite entry");
    if (T(3, 0) != 0 || T(3, 1) != 0 || T(3, 2) != 0 || T(3, 3) != 1)
      fail(source, "hand_eye.camera_pose", "last row must be [0 0 0 1]");
    const cv::Matx33d R = T.get_minor<3, 3>(0, 0);
    const cv::Matx33d E = R.t() * R - cv::Matx33d::eye();
    if (cv::norm(E, cv::NORM_INF) > 1e-6 || cv::determinant(R) < 0)
      fail(source, "hand_eye.camera_pose", "upper-left 3x3 is not a rotation");
  }
}

CameraConfig load_camera_config(const std::filesystem::path& file) {
  const std::string src = file.string();
  cv::FileStorage fs;
  try {
    if (!fs.open(src, cv::FileStorage::READ)) throw std::runtime_error(src + ": cannot open camera config");
  } catch (const cv::Exception& e) {
    throw std::runtime_error(src + ": not a valid OpenCV YAML file: " + e.what());
  }
  const cv::FileNode root = fs.root();
  CameraConfig c;
  c.camera.image_size.width = read_int(root, "image_width", src, "image_width");
  c.camera.image_size.height = read_int(root, "image_height", src, "image_height");

  const cv::Mat K = read_matrix(root, "camera_matrix", src, "camera_matrix", {3, 3, 3, 3, "3x3"});
  c.camera.K = cv::Matx33d(K);

  const cv::Mat d =
      read_matrix(root, "distortion_coefficients", src, "distortion_coefficients", {1, 14, 1, 14, "1xN or Nx1, N = 4..14"});
  if (d.rows != 1 && d.cols != 1) fail(src, "distortion_coefficients", "expected a row or column vector");
  if (d.total() < 4) fail(src, "distortion_coefficients", "expected 4 to 14 coefficients");
  c.camera.distortion.assign(d.begin<double>(), d.end<double>());

  c.working_distance_mm = read_number(root, "working_distance_mm", src, "working_distance_mm");

  const cv::FileNode fl = required(root, "flashes", src);
  if (!fl.isMap()) fail(src, "flashes", "expected a mapping");
  if (!fl["positions_mm"].empty()) {
    const cv::Mat p =
        read_matrix(fl, "positions_mm", src, "flashes.positions_mm", {kLedCount, kLedCount, 3, 3, "8x3 (x, y, z per LED)"});
    // The ring keys are ignored beside measured positions, but a count that disagrees with them
    // is a contradiction in the file.
    if (!fl["count"].empty() && !(fl["count"].isInt() && static_cast<int>(fl["count"]) == p.rows))
      fail(src, "flashes.count", "disagrees with the " + std::to_string(p.rows) + " rows of flashes.positions_mm");
    c.flashes = FlashRing{};
    for (int i = 0; i < p.rows; ++i)
      c.flashes.positions_mm.emplace_back(p.at<double>(i, 0), p.at<double>(i, 1), p.at<double>(i, 2));
  } else {
    FlashRing::Ring r;
    r.radius_mm = read_number(fl, "ring_radius_mm", src, "flashes.ring_radius_mm");
    r.first_angle_deg = read_number(fl, "first_angle_deg", src, "flashes.first_angle_deg");
    r.step_deg = read_number(fl, "step_deg", src, "flashes.step_deg");
    r.plane_z_mm = read_number(fl, "plane_z_mm", src, "flashes.plane_z_mm");
    r.count = read_int(fl, "count", src, "flashes.count");
    // Checked before FlashRing::regular allocates count positions.
    if (r.count != kLedCount) fail(src, "flashes.count", "an MFC has 8 LEDs, got " + std::to_string(r.count));
    if (!(r.radius_mm > 0) || r.radius_mm > 1000) fail(src, "flashes.ring_radius_mm", "must be in (0, 1000] mm");
    c.flashes = FlashRing::regular(r);
  }
  const cv::FileNode he = root["hand_eye"];
  if (!he.empty() && !he.isNone()) {
    if (!he.isMap()) fail(src, "hand_eye", "expected a mapping");
    HandEye h;
    const cv::FileNode mode = required(he, "mode", src);
    const std::string m = mode.isString() ? static_cast<std::string>(mode) : std::string();
    if (m == "eye_in_hand") h.mode = HandEye::Mode::eye_in_hand;
    else if (m == "eye_to_hand") h.mode = HandEye::Mode::eye_to_hand;
    else fail(src, "hand_eye.mode", "expected eye_in_hand or eye_to_hand");
    const cv::Mat T = read_matrix(he, "camera_pose", src, "hand_eye.camera_pose", {4, 4, 4, 4, "4x4"});
    h.camera_pose = cv::Matx44d(T);
    h.reprojection_rms_px = read_number(he, "reprojection_rms_px", src, "hand_eye.reprojection_rms_px");
    h.residual_rms_mm = read_number(he, "residual_rms_mm", src, "hand_eye.residual_rms_mm");
    h.views = read_int(he, "views", src, "hand_eye.views");
    c.hand_eye = h;
  }
  validate_camera_config(c, src);
  return c;
}

void save_camera_config(const CameraConfig& c, const std::filesystem::path& file) {
  validate_camera_config(c, file.string());
  cv::FileStorage fs(file.string(), cv::FileStorage::WRITE);
  if (!fs.isOpened()) throw std::runtime_error(file.string() + ": cannot write camera config");
  fs << "image_width" << c.camera.image_size.width;
  fs << "image_height" << c.camera.image_size.height;
  fs << "camera_matrix" << cv::Mat(c.camera.K);
  fs << "distortion_coefficients" << cv::Mat(c.camera.distortion).t();
  fs << "working_distance_mm" << c.working_distance_mm;
  fs << "flashes" << "{";
  if (c.flashes.ring) {
    fs << "ring_radius_mm" << c.flashes.ring->radius_mm;
    fs << "first_angle_deg" << c.flashes.ring->first_angle_deg;
    fs << "step_deg" << c.flashes.ring->step_deg;
    fs << "plane_z_mm" << c.flashes.ring->plane_z_mm;
    fs << "count" << c.flashes.ring->count;
  } else {
    cv::Mat p(static_cast<int>(c.flashes.positions_mm.size()), 3, CV_64F);
    for (int i = 0; i < p.rows; ++i)
      for (int k = 0; k < 3; ++k) p.at<double>(i, k) = c.flashes.positions_mm[static_cast<size_t>(i)][k];
    fs << "positions_mm" << p;
  }
  fs << "}";
  if (c.hand_eye) {
    fs << "hand_eye" << "{";
    fs << "mode" << (c.hand_eye->mode == HandEye::Mode::eye_in_hand ? "eye_in_hand" : "eye_to_hand");
    fs << "camera_pose" << cv::Mat(c.hand_eye->camera_pose);
    fs << "reprojection_rms_px" << c.hand_eye->reprojection_rms_px;
    fs << "residual_rms_mm" << c.hand_eye->residual_rms_mm;
    fs << "views" << c.hand_eye->views;
    fs << "}";
  }
}

}  // namespace mfcd::vision
