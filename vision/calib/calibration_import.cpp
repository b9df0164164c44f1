#include "vision/calib/calibration_import.hpp"
#include "vision/common/scalar_text.hpp"

#include "vision/calib/board.hpp"

#include <yaml-cpp/yaml.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <limits>
#include <set>
#include <sstream>

namespace mfcd::vision::calib {

namespace fs = std::filesystem;

namespace {

// Image sizes the camera file accepts (validate_camera_config).
constexpr int kMaxImageSide = 20000;
// The reason a fisheye lens is refused, in every format.
constexpr const char* kFisheyeRefused =
    "fisheye lenses are not supported (mfcd's camera model is the pinhole with polynomial distortion)";

std::string format_number(double v) {
  std::ostringstream s;
  s.precision(10);
  s << v;
  return s.str();
}

// A YAML float scalar: what strtod reads, plus YAML's .nan / .inf spellings (OpenCV's
// FileStorage writes .Nan, .Inf and -.Inf). Non-finite values are returned as such so that the
// caller can say "not finite" rather than "not a number".
std::optional<double> parse_float(const std::string& s) {
  if (s.empty()) return std::nullopt;
  std::string t = s;
  double sign = 1;
  if (!t.empty() && (t[0] == '+' || t[0] == '-')) {
    if (t[0] == '-') sign = -1;
    t = t.substr(1);
  }
  if (t == ".inf" || t == ".Inf" || t == ".INF") return sign * std::numeric_limits<double>::infinity();
  if (s == ".nan" || s == ".NaN" || s == ".NAN" || s == ".Nan") return std::numeric_limits<double>::quiet_NaN();
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (*end != '\0') return std::nullopt;
  return v;
}

// A matrix as both formats write one: a mapping with rows, cols, data (row-major) and, in
// OpenCV's files, dt (the element type).
struct Matrix {
  int rows = 0, cols = 0;
  std::vector<double> data;
  std::vector<std::string> text;  // the scalars as written, for messages
  YAML::Node node;
  double at(int r, int c) const { return data[static_cast<size_t>(r * cols + c)]; }
};

// Reads the keys of a parsed calibration file. Every refusal is a CalibrationError
// "<file>:<line>: key '<key>': <why>" (the line where yaml-cpp has a mark for the node).
class Reader {
 public:
  explicit Reader(std::string source) : source_(std::move(source)) {}

  [[noreturn]] void fail_at(const YAML::Node& n, const std::string& key, const std::string& why) const {
    const int line = n.IsDefined() && n.Mark().line >= 0 ? n.Mark().line + 1 : 0;
    throw CalibrationError((line > 0 ? source_ + ":" + std::to_string(line) : source_) + ": key '" + key + "': " + why);
  }

  // The node under `name` of the mapping `parent`, or an undefined node.
  static YAML::Node child(const YAML::Node& parent, const std::string& name) {
    if (!parent.IsMap()) return YAML::Node(YAML::NodeType::Undefined);
    for (const auto& kv : parent)
      if (kv.first.IsScalar() && kv.first.Scalar() == name) return kv.second;
    return YAML::Node(YAML::NodeType::Undefined);
  }
  static bool present(const YAML::Node& n) { return n.IsDefined() && !n.IsNull(); }

  // The first of `names` present in `parent`; `used` is set to its name (to the first name when
  // none is present, so that "missing" names the key as current files spell it).
  static YAML::Node any_of(const YAML::Node& parent, std::initializer_list<const char*> names, std::string& used) {
    for (const char* name : names) {
      const YAML::Node n = child(parent, name);
      if (present(n)) {
        used = name;
        return n;
      }
    }
    used = *names.begin();
    return YAML::Node(YAML::NodeType::Undefined);
  }

  YAML::Node required(const YAML::Node& parent, std::initializer_list<const char*> names, std::string& used) const {
    const YAML::Node n = any_of(parent, names, used);
    if (!present(n)) fail_at(parent, used, "missing");
    return n;
  }

  int integer(const YAML::Node& n, const std::string& key) const {
    const std::string s = n.IsScalar() ? n.Scalar() : std::string();
    const std::optional<int> v = parse_int(s);
    if (!v) fail_at(n, key, "expected an integer, got '" + s + "'");
    return *v;
  }

  // A number, possibly non-finite.
  double number(const YAML::Node& n, const std::string& key) const {
    const std::string s = n.IsScalar() ? n.Scalar() : std::string();
    const std::optional<double> v = parse_float(s);
    if (!v) fail_at(n, key, "expected a number, got '" + s + "'");
    return *v;
  }

  // rows x cols checked against the length of data before anything is indexed by them; dt, when
  // present, must be one number per element.
  Matrix matrix(const YAML::Node& n, const std::string& key) const {
    if (!n.IsMap()) fail_at(n, key, "expected a matrix (a mapping with rows, cols and data)");
    std::string name;
    Matrix m;
    m.node = n;
    m.rows = integer(required(n, {"rows"}, name), key + ".rows");
    m.cols = integer(required(n, {"cols"}, name), key + ".cols");
    if (m.rows < 0 || m.cols < 0) fail_at(n, key, "negative rows or cols");
    const YAML::Node dt = child(n, "dt");
    if (present(dt)) {
      const std::string type = dt.IsScalar() ? dt.Scalar() : std::string();
      if (type.size() != 1 || std::string("ucwsifd").find(type[0]) == std::string::npos)
        fail_at(dt, key, "expected 'dt' to be one number per element (d, f, ...), got '" + type + "'");
    }
    const YAML::Node data = required(n, {"data"}, name);
    const long long expected = static_cast<long long>(m.rows) * m.cols;
    if (!data.IsSequence() || static_cast<long long>(data.size()) != expected)
      fail_at(data, key,
              "'data' must list rows x cols = " + std::to_string(m.rows) + " x " + std::to_string(m.cols) + " = " +
                  std::to_string(expected) + " numbers" +
                  (data.IsSequence() ? ", it lists " + std::to_string(data.size()) : std::string()));
    for (size_t i = 0; i < data.size(); ++i) {
      m.data.push_back(number(data[i], key));
      m.text.push_back(data[i].Scalar());
    }
    return m;
  }

  const std::string& source() const { return source_; }

 private:
  std::string source_;
};

cv::Size read_image_size(const YAML::Node& root, const Reader& rd, bool opencv, std::set<std::string>& read) {
  int side[2] = {0, 0};
  for (int i = 0; i < 2; ++i) {
    std::string key;
    const YAML::Node n = i == 0 ? rd.required(root, {"image_width", opencv ? "image_Width" : "image_width"}, key)
                                : rd.required(root, {"image_height", opencv ? "image_Height" : "image_height"}, key);
    side[i] = rd.integer(n, key);
    if (side[i] < 1 || side[i] > kMaxImageSide)
      rd.fail_at(n, key, "must be in 1.." + std::to_string(kMaxImageSide) + " pixels, got " + std::to_string(side[i]));
    read.insert(key);
  }
  return {side[0], side[1]};
}

cv::Matx33d read_camera_matrix(const YAML::Node& root, const Reader& rd, bool opencv, std::set<std::string>& read) {
  std::string key;
  const YAML::Node n = rd.required(root, {"camera_matrix", opencv ? "Camera_Matrix" : "camera_matrix"}, key);
  const Matrix m = rd.matrix(n, key);
  if (m.rows != 3 || m.cols != 3)
    rd.fail_at(n, key, "a " + std::to_string(m.rows) + "x" + std::to_string(m.cols) + " matrix, expected 3x3");
  cv::Matx33d K;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      K(r, c) = m.at(r, c);
      if (!std::isfinite(K(r, c)))
        rd.fail_at(n, key,
                   "entry (" + std::to_string(r) + ", " + std::to_string(c) + ") is not finite (" +
                       m.text[static_cast<size_t>(r * 3 + c)] + ")");
    }
  if (!(K(0, 0) > 0) || !(K(1, 1) > 0))
    rd.fail_at(n, key,
               "the focal lengths must be positive, got fx = " + m.text[0] + " (entry (0, 0)), fy = " + m.text[4] +
                   " (entry (1, 1))");
  if (K(1, 0) != 0 || K(2, 0) != 0 || K(2, 1) != 0 || K(2, 2) != 1)
    rd.fail_at(n, key, "not of the form [fx s cx; 0 fy cy; 0 0 1]");
  read.insert(key);
  return K;
}

// The coefficients of a 1xN or Nx1 matrix (N may be 0), each finite.
std::vector<double> read_coefficients(const YAML::Node& n, const std::string& key, const Reader& rd) {
  const Matrix m = rd.matrix(n, key);
  if (m.rows != 1 && m.cols != 1 && !m.data.empty())
    rd.fail_at(
        n, key,
        "a " + std::to_string(m.rows) + "x" + std::to_string(m.cols) + " matrix, expected one row or one column");
  for (size_t i = 0; i < m.data.size(); ++i)
    if (!std::isfinite(m.data[i]))
      rd.fail_at(n, key, "coefficient " + std::to_string(i) + " is not finite (" + m.text[i] + ")");
  return m.data;
}

// OpenCV's calibration samples (and the tutorial's OpenCV 2.x output with capitalised keys).
void read_opencv(const YAML::Node& root, const Reader& rd, ForeignCalibration& f, std::set<std::string>& read) {
  f.camera.image_size = read_image_size(root, rd, true, read);
  f.camera.K = read_camera_matrix(root, rd, true, read);
  // The tutorial writes fisheye_model (0 or 1) since OpenCV 4.x; with 1 its coefficients are
  // cv::fisheye's k1..k4, which no pinhole undistortion reads.
  const YAML::Node fisheye = Reader::child(root, "fisheye_model");
  if (Reader::present(fisheye)) {
    if (rd.integer(fisheye, "fisheye_model") != 0) rd.fail_at(fisheye, "fisheye_model", kFisheyeRefused);
    read.insert("fisheye_model");
  }
  std::string key;
  const YAML::Node dn = rd.required(root, {"distortion_coefficients", "Distortion_Coefficients"}, key);
  const std::vector<double> d = read_coefficients(dn, key, rd);
  // The counts cv::calibrateCamera produces: k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4 [tx ty]]]].
  if (d.size() != 4 && d.size() != 5 && d.size() != 8 && d.size() != 12 && d.size() != 14)
    rd.fail_at(dn, key,
               std::to_string(d.size()) +
                   " coefficients; OpenCV's pinhole models have 4, 5, 8, 12 or 14 (k1 k2 p1 p2 [k3 [k4 k5 k6 "
                   "[s1 s2 s3 s4 [tx ty]]]])");
  f.camera.distortion = d;
  f.distortion_model = "OpenCV, " + std::to_string(d.size()) + " coefficients";
  read.insert(key);

  const YAML::Node rms = Reader::any_of(root, {"avg_reprojection_error", "Avg_Reprojection_Error"}, key);
  const std::optional<double> e = rms.IsScalar() ? parse_float(rms.Scalar()) : std::nullopt;
  if (e) {
    std::string note = key + " " + format_number(*e) + " px";
    const YAML::Node frames = Reader::any_of(root, {"nframes", "nr_of_frames", "nrOfFrames"}, key);
    if (frames.IsScalar()) note += " over " + frames.Scalar() + " views";
    f.notes.push_back(note + " (as the file states)");
  }
}

// A ROS camera_info YAML (camera_calibration_parsers, cameracalibrator.py).
void read_ros(const YAML::Node& root, const Reader& rd, ForeignCalibration& f, std::set<std::string>& read) {
  f.camera.image_size = read_image_size(root, rd, false, read);
  f.camera.K = read_camera_matrix(root, rd, false, read);

  const YAML::Node model = Reader::child(root, "distortion_model");
  std::string name = "plumb_bob";
  if (Reader::present(model)) {
    if (!model.IsScalar()) rd.fail_at(model, "distortion_model", "expected a name (plumb_bob, rational_polynomial)");
    name = model.Scalar();
    read.insert("distortion_model");
  } else {
    f.notes.push_back("no distortion_model: plumb_bob assumed (as camera_calibration_parsers does)");
  }
  // sensor_msgs/distortion_models: plumb_bob and rational_polynomial are OpenCV's 5- and
  // 8-coefficient models in OpenCV's order (k1 k2 t1 t2 k3 [k4 k5 k6]); equidistant is cv::fisheye.
  size_t count = 0;
  const char* order = "";
  if (name == "plumb_bob") {
    count = 5;
    order = "k1 k2 t1 t2 k3";
  } else if (name == "rational_polynomial") {
    count = 8;
    order = "k1 k2 t1 t2 k3 k4 k5 k6";
  } else if (name == "equidistant" || name == "fisheye") {
    rd.fail_at(model, "distortion_model", "'" + name + "': " + kFisheyeRefused);
  } else {
    rd.fail_at(model, "distortion_model", "'" + name + "' is not imported (plumb_bob and rational_polynomial are)");
  }
  std::string key;
  const YAML::Node dn = rd.required(root, {"distortion_coefficients"}, key);
  const std::vector<double> d = read_coefficients(dn, key, rd);
  if (d.size() != count)
    rd.fail_at(
        dn, key,
        name + " has " + std::to_string(count) + " coefficients (" + order + "), got " + std::to_string(d.size()));
  f.camera.distortion = d;
  f.distortion_model = name;
  read.insert(key);

  const YAML::Node cam = Reader::child(root, "camera_name");
  if (cam.IsScalar()) f.notes.push_back("camera_name '" + cam.Scalar() + "'");
  // A stereo camera's rectification turns the image; K and D still describe the unrectified image,
  // which is what is imported.
  const YAML::Node rect = Reader::child(root, "rectification_matrix");
  if (Reader::present(rect)) {
    try {
      const Matrix R = rd.matrix(rect, "rectification_matrix");
      if (R.rows == 3 && R.cols == 3 && cv::Matx33d(R.data.data()) != cv::Matx33d::eye())
        f.notes.push_back(
            "rectification_matrix is not the identity (a stereo pair's camera): K and D of the unrectified image are "
            "imported, R and P are not used");
    } catch (const CalibrationError&) {
      // Not used: a malformed one is ignored like the other keys not read.
    }
  }
}

// CameraConfig's defaults (the simulated camera's MFC keys). Out of line: GCC 12 inlining a
// default-constructed CameraConfig into import_calibration warns falsely (-Wdangling-pointer).
[[gnu::noinline]] CameraConfig default_config() { return CameraConfig{}; }

CameraConfig base_config(const fs::path& file) { return file.empty() ? default_config() : load_camera_config(file); }

}  // namespace

const char* to_string(ForeignFormat format) {
  return format == ForeignFormat::opencv ? "OpenCV calibration sample" : "ROS camera_info";
}

ForeignCalibration read_foreign_calibration(const fs::path& file) {
  const std::string src = file.string();
  std::ifstream in(file, std::ios::binary);
  if (!in) throw CalibrationError(src + ": cannot open the calibration file");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());

  // OpenCV's samples write XML when the output name ends in .xml; yaml-cpp cannot read it, and
  // OpenCV's own XML reader is not used on files from elsewhere (docs/fuzzing.md).
  size_t first = text.rfind("\xEF\xBB\xBF", 0) == 0 ? 3 : 0;
  first = text.find_first_not_of(" \t\r\n", first);
  if (first != std::string::npos && text[first] == '<')
    throw CalibrationError(src +
                           ": an XML file; only YAML is imported (OpenCV's calibration samples write YAML when the "
                           "output file name ends in .yml or .yaml)");
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw CalibrationError(src + (e.mark.line >= 0 ? ":" + std::to_string(e.mark.line + 1) : std::string()) +
                           ": not valid YAML: " + e.msg);
  }
  if (!root.IsMap()) throw CalibrationError(src + ": not a calibration file (the top level is not a mapping of keys)");

  const Reader rd(src);
  for (const char* key : {"working_distance_mm", "flashes"})
    if (Reader::present(Reader::child(root, key)))
      throw CalibrationError(src + ": already a camera file of this project (it has '" + key +
                             "'): use it as it is, nothing to import");

  ForeignCalibration f;
  bool ros = false;
  for (const char* key : {"distortion_model", "camera_name", "rectification_matrix", "projection_matrix"})
    ros = ros || Reader::present(Reader::child(root, key));
  f.format = ros ? ForeignFormat::ros : ForeignFormat::opencv;
  std::set<std::string> read;
  try {
    if (!ros) {
      std::string key;
      if (!Reader::present(Reader::any_of(root, {"camera_matrix", "Camera_Matrix"}, key)))
        rd.fail_at(root, "camera_matrix",
                   "missing (neither an OpenCV calibration nor a ROS camera_info file has been recognised)");
      read_opencv(root, rd, f, read);
    } else {
      read_ros(root, rd, f, read);
    }
  } catch (const YAML::Exception& e) {
    // Reader checks each node's type before using it; a use yaml-cpp still refused is named too.
    throw CalibrationError(src + ": malformed calibration file: " + e.what());
  }
  for (const auto& kv : root) {
    const std::string key = kv.first.IsScalar() ? kv.first.Scalar() : std::string("?");
    (read.count(key) ? f.keys_read : f.keys_unused).push_back(key);
  }
  return f;
}

std::vector<std::string> CalibrationImport::defaults_used() const {
  std::vector<std::string> keys;
  for (const auto& k : mfc_keys)
    if (k.from == MfcKeySource::From::default_value) keys.push_back(k.key);
  return keys;
}

std::string CalibrationImport::summary(const fs::path& file) const {
  const auto join = [](const std::vector<std::string>& v) {
    std::string s;
    for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
    return s.empty() ? std::string("none") : s;
  };
  const PinholeCamera& c = source.camera;
  std::ostringstream s;
  s << "read " << file.string() << " as " << (source.format == ForeignFormat::ros ? "a " : "an ")
    << to_string(source.format) << " file\n";
  s << "  read: " << join(source.keys_read) << '\n';
  s << "  image " << c.image_size.width << " x " << c.image_size.height << " px; fx " << format_number(c.fx())
    << ", fy " << format_number(c.fy()) << ", cx " << format_number(c.cx()) << ", cy " << format_number(c.cy())
    << " px, skew " << format_number(c.K(0, 1)) << '\n';
  s << "  distortion (" << source.distortion_model << "):";
  for (double d : c.distortion) s << ' ' << format_number(d);
  s << '\n';
  for (const auto& n : source.notes) s << "  " << n << '\n';
  s << "  not used: " << join(source.keys_unused) << '\n';
  s << "MFC keys (not in " << file.filename().string() << "):\n";
  for (const auto& k : mfc_keys) {
    const std::string from = k.from == MfcKeySource::From::option ? "given"
                             : k.from == MfcKeySource::From::base ? "from " + base_camera_file.string()
                                                                  : "default";
    s << "  " << k.key << ": " << k.value << " (" << from << ")\n";
  }
  return s.str();
}

CalibrationImport import_calibration(const fs::path& file, const MfcKeyOptions& options) {
  const auto check = [](const std::optional<double>& v, const std::string& key, double lo, double hi,
                        const std::string& range) {
    if (v && (!std::isfinite(*v) || !(*v > lo) || *v > hi))
      throw CalibrationError("key '" + key + "': must be in " + range + ", got " + format_number(*v));
  };
  const double inf = std::numeric_limits<double>::infinity();
  check(options.working_distance_mm, "working_distance_mm", 0, 1e5, "(0, 100000] mm");
  check(options.ring_radius_mm, "flashes.ring_radius_mm", 0, 1000, "(0, 1000] mm");
  check(options.first_angle_deg, "flashes.first_angle_deg", -inf, inf, "finite degrees");
  check(options.step_deg, "flashes.step_deg", -inf, inf, "finite degrees");
  check(options.plane_z_mm, "flashes.plane_z_mm", -inf, inf, "finite mm");

  CalibrationImport r;
  r.source = read_foreign_calibration(file);
  r.base_camera_file = options.base_camera_file;
  const bool has_base = !options.base_camera_file.empty();
  const CameraConfig base = base_config(options.base_camera_file);
  CameraConfig& c = r.config;
  c = base;
  c.camera = r.source.camera;

  const auto take = [&](const std::optional<double>& given, double from_base, double fallback, double& out,
                        const std::string& key, const std::string& unit, bool base_has_it) {
    MfcKeySource k;
    k.key = key;
    if (given) {
      out = *given;
      k.from = MfcKeySource::From::option;
    } else if (base_has_it) {
      out = from_base;
      k.from = MfcKeySource::From::base;
    } else {
      out = fallback;
      k.from = MfcKeySource::From::default_value;
    }
    k.value = format_number(out) + " " + unit;
    r.mfc_keys.push_back(k);
  };
  take(options.working_distance_mm, base.working_distance_mm, default_config().working_distance_mm,
       c.working_distance_mm, "working_distance_mm", "mm", has_base);

  const bool ring_given = options.ring_radius_mm || options.first_angle_deg || options.step_deg || options.plane_z_mm;
  if (has_base && !ring_given && !base.flashes.ring) {
    // Measured LED positions in the base file are kept as they are.
    r.mfc_keys.push_back({"flashes.positions_mm", MfcKeySource::From::base, "8 measured LED positions"});
  } else {
    const FlashRing::Ring fallback;
    const bool base_ring = has_base && base.flashes.ring.has_value();
    const FlashRing::Ring from_base = base_ring ? *base.flashes.ring : fallback;
    FlashRing::Ring ring;
    take(options.ring_radius_mm, from_base.radius_mm, fallback.radius_mm, ring.radius_mm, "flashes.ring_radius_mm",
         "mm", base_ring);
    take(options.first_angle_deg, from_base.first_angle_deg, fallback.first_angle_deg, ring.first_angle_deg,
         "flashes.first_angle_deg", "deg", base_ring);
    take(options.step_deg, from_base.step_deg, fallback.step_deg, ring.step_deg, "flashes.step_deg", "deg", base_ring);
    take(options.plane_z_mm, from_base.plane_z_mm, fallback.plane_z_mm, ring.plane_z_mm, "flashes.plane_z_mm", "mm",
         base_ring);
    c.flashes = FlashRing::regular(ring);
  }
  if (c.hand_eye)
    r.mfc_keys.push_back({"hand_eye", MfcKeySource::From::base,
                          "kept; it was computed with the previous intrinsics: redo hand-eye calibration"});
  try {
    validate_camera_config(c, file.string() + " (imported)");
  } catch (const std::runtime_error& e) {
    throw CalibrationError(e.what());
  }
  return r;
}

}  // namespace mfcd::vision::calib
