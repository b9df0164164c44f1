#include "vision/camera/camera.hpp"
#include "base/unique_fd.hpp"
#include "vision/common/scalar_text.hpp"

#include <fcntl.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace mfcd::vision {

namespace {

[[noreturn]] void fail(const std::string& source, const std::string& key, const std::string& why) {
  throw std::runtime_error(source + ": key '" + key + "': " + why);
}

// The number of LEDs of an MFC (docs/camera.md): flashes.count and flashes.positions_mm rows.
constexpr int kLedCount = 8;

// The shape an !!opencv-matrix key must have, and how a refusal states it.
struct MatrixShape {
  int min_rows, max_rows, min_cols, max_cols;
  const char* expected;
};

// Reads the keys of a parsed camera file. Every refusal is a std::runtime_error
// "<file>:<line>: key '<key>': <why>" (the line where yaml-cpp has a mark for the node).
class Reader {
 public:
  explicit Reader(std::string source) : source_(std::move(source)) {}

  [[noreturn]] void fail_at(const YAML::Node& n, const std::string& key, const std::string& why) const {
    const int line = n.IsDefined() && n.Mark().line >= 0 ? n.Mark().line + 1 : 0;
    fail(line > 0 ? source_ + ":" + std::to_string(line) : source_, key, why);
  }

  // The node under `name` of the mapping `parent`, or an undefined node.
  static YAML::Node child(const YAML::Node& parent, const char* name) {
    if (!parent.IsMap()) return YAML::Node(YAML::NodeType::Undefined);
    for (const auto& kv : parent)
      if (kv.first.IsScalar() && kv.first.Scalar() == name) return kv.second;
    return YAML::Node(YAML::NodeType::Undefined);
  }
  static bool present(const YAML::Node& n) { return n.IsDefined() && !n.IsNull(); }

  YAML::Node required(const YAML::Node& parent, const char* name, const std::string& key) const {
    const YAML::Node n = child(parent, name);
    if (!present(n)) fail_at(parent, key, "missing");
    return n;
  }

  int integer(const YAML::Node& n, const std::string& key) const {
    const std::string s = n.IsScalar() ? n.Scalar() : std::string();
    const std::optional<int> v = parse_int(s);
    if (!v) fail_at(n, key, "expected an integer");
    return *v;
  }
  int integer(const YAML::Node& parent, const char* name, const std::string& key) const {
    return integer(required(parent, name, key), key);
  }

  double number(const YAML::Node& n, const std::string& key) const {
    const std::string s = n.IsScalar() ? n.Scalar() : std::string();
    char* end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    if (s.empty() || *end != '\0' || !std::isfinite(v)) fail_at(n, key, "expected a number");
    return v;
  }
  double number(const YAML::Node& parent, const char* name, const std::string& key) const {
    return number(required(parent, name, key), key);
  }

  // An !!opencv-matrix (rows, cols, dt, data), its size checked against `shape` and its data
  // length against rows x cols before the matrix is allocated.
  cv::Mat matrix(const YAML::Node& parent, const char* name, const std::string& key, const MatrixShape& shape) const {
    const YAML::Node n = required(parent, name, key);
    if (!n.IsMap()) fail_at(n, key, "expected an !!opencv-matrix");
    const int r = integer(n, "rows", key + ".rows"), c = integer(n, "cols", key + ".cols");
    if (r < shape.min_rows || r > shape.max_rows || c < shape.min_cols || c > shape.max_cols)
      fail_at(n, key, "a " + std::to_string(r) + "x" + std::to_string(c) + " matrix, expected " + shape.expected);
    // One channel of a number type: u c w s i f d (OpenCV's type letters).
    const YAML::Node dt = required(n, "dt", key + ".dt");
    const std::string type = dt.IsScalar() ? dt.Scalar() : std::string();
    if (type.size() != 1 || std::string("ucwsifd").find(type[0]) == std::string::npos)
      fail_at(dt, key, "expected 'dt' to be one number type (d, f, i, ...), got '" + type + "'");
    const YAML::Node data = required(n, "data", key + ".data");
    if (!data.IsSequence() || data.size() != static_cast<size_t>(r) * static_cast<size_t>(c))
      fail_at(data, key, "'data' must list rows x cols = " + std::to_string(r * c) + " numbers");
    cv::Mat m(r, c, CV_64F);
    for (int i = 0; i < r * c; ++i) m.at<double>(i / c, i % c) = number(data[static_cast<size_t>(i)], key);
    return m;
  }

 private:
  std::string source_;
};

CameraConfig read_camera_config(const YAML::Node& root, const Reader& rd) {
  CameraConfig c;
  // OpenCV's calibration tutorial writes fisheye_model: 1 for cv::fisheye's k1..k4: read as
  // pinhole coefficients they would undistort every frame wrongly, so such a file is refused.
  const YAML::Node fisheye = Reader::child(root, "fisheye_model");
  if (Reader::present(fisheye) && rd.integer(fisheye, "fisheye_model") != 0)
    rd.fail_at(fisheye, "fisheye_model",
               "fisheye lenses are not supported: mfcd's camera model is the pinhole with polynomial distortion");
  c.camera.image_size.width = rd.integer(root, "image_width", "image_width");
  c.camera.image_size.height = rd.integer(root, "image_height", "image_height");
  c.camera.K = cv::Matx33d(rd.matrix(root, "camera_matrix", "camera_matrix", {3, 3, 3, 3, "3x3"}));

  const cv::Mat d =
      rd.matrix(root, "distortion_coefficients", "distortion_coefficients", {1, 14, 1, 14, "1xN or Nx1, N = 4..14"});
  if ((d.rows != 1 && d.cols != 1) || d.total() < 4)
    rd.fail_at(Reader::child(root, "distortion_coefficients"), "distortion_coefficients",
               "expected 4 to 14 coefficients in a row or a column");
  c.camera.distortion.assign(d.begin<double>(), d.end<double>());

  c.working_distance_mm = rd.number(root, "working_distance_mm", "working_distance_mm");

  const YAML::Node fl = rd.required(root, "flashes", "flashes");
  if (!fl.IsMap()) rd.fail_at(fl, "flashes", "expected a mapping");
  const YAML::Node count = Reader::child(fl, "count");
  if (Reader::present(Reader::child(fl, "positions_mm"))) {
    const cv::Mat p =
        rd.matrix(fl, "positions_mm", "flashes.positions_mm", {kLedCount, kLedCount, 3, 3, "8x3 (x, y, z per LED)"});
    // The ring keys are ignored beside measured positions, but a count that disagrees with them
    // is a contradiction in the file.
    if (Reader::present(count) && rd.integer(count, "flashes.count") != p.rows)
      rd.fail_at(count, "flashes.count",
                 "disagrees with the " + std::to_string(p.rows) + " rows of flashes.positions_mm");
    c.flashes = FlashRing{};
    for (int i = 0; i < p.rows; ++i)
      c.flashes.positions_mm.emplace_back(p.at<double>(i, 0), p.at<double>(i, 1), p.at<double>(i, 2));
  } else {
    FlashRing::Ring r;
    r.radius_mm = rd.number(fl, "ring_radius_mm", "flashes.ring_radius_mm");
    r.first_angle_deg = rd.number(fl, "first_angle_deg", "flashes.first_angle_deg");
    r.step_deg = rd.number(fl, "step_deg", "flashes.step_deg");
    r.plane_z_mm = rd.number(fl, "plane_z_mm", "flashes.plane_z_mm");
    r.count = rd.integer(fl, "count", "flashes.count");
    // Checked before FlashRing::regular allocates count positions.
    if (r.count != kLedCount) rd.fail_at(count, "flashes.count", "an MFC has 8 LEDs, got " + std::to_string(r.count));
    if (!(r.radius_mm > 0) || r.radius_mm > 1000)
      rd.fail_at(Reader::child(fl, "ring_radius_mm"), "flashes.ring_radius_mm", "must be in (0, 1000] mm");
    c.flashes = FlashRing::regular(r);
  }
  const YAML::Node he = Reader::child(root, "hand_eye");
  if (Reader::present(he)) {
    if (!he.IsMap()) rd.fail_at(he, "hand_eye", "expected a mapping");
    HandEye h;
    const YAML::Node mode = rd.required(he, "mode", "hand_eye.mode");
    const std::string m = mode.IsScalar() ? mode.Scalar() : std::string();
    if (m == "eye_in_hand")
      h.mode = HandEye::Mode::eye_in_hand;
    else if (m == "eye_to_hand")
      h.mode = HandEye::Mode::eye_to_hand;
    else
      rd.fail_at(mode, "hand_eye.mode", "expected eye_in_hand or eye_to_hand");
    h.camera_pose = cv::Matx44d(rd.matrix(he, "camera_pose", "hand_eye.camera_pose", {4, 4, 4, 4, "4x4"}));
    h.reprojection_rms_px = rd.number(he, "reprojection_rms_px", "hand_eye.reprojection_rms_px");
    h.residual_rms_mm = rd.number(he, "residual_rms_mm", "hand_eye.residual_rms_mm");
    h.views = rd.integer(he, "views", "hand_eye.views");
    c.hand_eye = h;
  }
  return c;
}

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
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error(src + ": cannot open camera config");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // Read with yaml-cpp, not cv::FileStorage, which save_camera_config writes with: OpenCV 4.6's
  // parser picks XML by the content and dereferences NULL on "<?xml n=\0", and its YAML parser
  // loops forever on "%YAML:1.\n t:d\no 0-\n" (docs/fuzzing.md). FileStorage's "%YAML:1.0"
  // first line is an unknown directive to yaml-cpp, its !!opencv-matrix tag is not needed.
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(src + (e.mark.line >= 0 ? ":" + std::to_string(e.mark.line + 1) : std::string()) +
                             ": not valid YAML: " + e.msg);
  }
  if (!root.IsMap()) throw std::runtime_error(src + ": not a camera config (the top level is not a mapping)");
  CameraConfig c;
  try {
    c = read_camera_config(root, Reader(src));
  } catch (const YAML::Exception& e) {
    // Reader checks each node's type before using it; a use yaml-cpp still refused is named too.
    throw std::runtime_error(src + ": malformed camera config: " + e.what());
  }
  validate_camera_config(c, src);
  return c;
}

namespace {

// The YAML text of a camera config. Made in memory: FileStorage writing a file checks none of
// its writes, so a full disk would leave a truncated file without an error.
std::string camera_config_yaml(const CameraConfig& c) {
  cv::FileStorage fs(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY | cv::FileStorage::FORMAT_YAML);
  fs << "image_width" << c.camera.image_size.width;
  fs << "image_height" << c.camera.image_size.height;
  fs << "camera_matrix" << cv::Mat(c.camera.K);
  fs << "distortion_coefficients" << cv::Mat(c.camera.distortion).t();
  fs << "working_distance_mm" << c.working_distance_mm;
  fs << "flashes"
     << "{";
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
    fs << "hand_eye"
       << "{";
    fs << "mode" << (c.hand_eye->mode == HandEye::Mode::eye_in_hand ? "eye_in_hand" : "eye_to_hand");
    fs << "camera_pose" << cv::Mat(c.hand_eye->camera_pose);
    fs << "reprojection_rms_px" << c.hand_eye->reprojection_rms_px;
    fs << "residual_rms_mm" << c.hand_eye->residual_rms_mm;
    fs << "views" << c.hand_eye->views;
    fs << "}";
  }
  return fs.releaseAndGetString();
}

[[noreturn]] void write_failed(const std::filesystem::path& file, const char* what, int error) {
  throw std::runtime_error(file.string() + ": " + what + ": " + std::strerror(error));
}

}  // namespace

void save_camera_config(const CameraConfig& c, const std::filesystem::path& file) {
  validate_camera_config(c, file.string());
  // YAML whatever the file's extension: load_camera_config reads YAML only.
  const std::string text = camera_config_yaml(c);
  UniqueFd fd(::open(file.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644));
  if (!fd) write_failed(file, "cannot write camera config", errno);
  for (size_t done = 0; done < text.size();) {
    const ssize_t n = ::write(fd.get(), text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) write_failed(file, "cannot write camera config", n < 0 ? errno : EIO);
    done += static_cast<size_t>(n);
  }
  // close() reports what a delayed write-back could not store (NFS, some FUSE file systems).
  if (::close(fd.release()) != 0) write_failed(file, "cannot write camera config", errno);
}

}  // namespace mfcd::vision
