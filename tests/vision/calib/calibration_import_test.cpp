// Importing calibrations made with OpenCV's samples and with ROS into the camera config.
//
// The files in tests/vision/calib/foreign/ are byte for byte what the tools wrote, but for the
// 2.x one (rewritten by hand from opencv_tutorial.yml):
//   opencv_sample.yml            OpenCV 4.6's samples/cpp/calibration.cpp (Debian's opencv-doc), run
//                                with -w=9 -h=6 -s=25 -oe on six rendered views of a board
//   opencv_tutorial.yml          the key sequence of OpenCV 4.x's tutorial_camera_calibration
//                                (saveCameraParams, its default flags, extrinsics written), through
//                                OpenCV 4.6's FileStorage; opencv_tutorial_fisheye.yml: the same with
//                                its fisheye model
//   opencv_tutorial_2x.yml       opencv_tutorial.yml in the tutorial's OpenCV 2.x form (as
//                                out_camera_data.yml in OpenCV's sources): capitalised keys,
//                                no '---', three-digit exponents
//   ros_plumb_bob.yaml, ros_rational_polynomial.yaml, ros_equidistant.yaml
//                                camera_calibration_parsers 1.12 (Debian's
//                                camera-calibration-parsers-tools `convert`, the library's YAML writer;
//                                no header comment, no final newline)
//   ros_ost.yaml                 ost.yaml as ROS's cameracalibrator.py formats it (numpy 1.24)
// The refusals edit those texts one key at a time.
#include "vision/calib/calibration_import.hpp"

#include "vision/calib/board.hpp"
#include "vision/calib/store.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <limits>
#include <sstream>

using namespace mfcd::vision;
using namespace mfcd::vision::calib;
namespace fs = std::filesystem;

namespace {

const fs::path kForeign = fs::path(MFC_SOURCE_DIR) / "tests/vision/calib/foreign";

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

fs::path fresh_dir(const std::string& name) {
  const fs::path d = fs::path(MFC_BINARY_DIR) / "test-calib-import" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

fs::path write(const fs::path& file, const std::string& text) {
  std::ofstream(file, std::ios::binary) << text;
  return file;
}

// `text` with its one occurrence of `from` replaced by `to`; fails the test when `from` is not
// there once, so that an edit cannot silently leave the file valid.
std::string edited(const std::string& text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << "'" << from << "' not in the text";
  EXPECT_EQ(text.find(from, at + 1), std::string::npos) << "'" << from << "' more than once";
  if (at == std::string::npos) return text;
  return text.substr(0, at) + to + text.substr(at + from.size());
}

// The message of the CalibrationError `f` throws, "" when it throws nothing.
template <class F>
std::string refusal(F f) {
  try {
    f();
  } catch (const CalibrationError& e) {
    return e.what();
  }
  return "";
}

bool contains(const std::vector<std::string>& v, const std::string& x) {
  return std::find(v.begin(), v.end(), x) != v.end();
}

// The file written from `config` loads with load_camera_config to the same intrinsics, bit for bit.
void expect_round_trip(const CameraConfig& config, const fs::path& dir) {
  const fs::path out = dir / "camera.yaml";
  CalibrationStore(out).apply(config);
  const CameraConfig back = load_camera_config(out);
  EXPECT_EQ(back.camera.image_size, config.camera.image_size);
  EXPECT_EQ(back.camera.K, config.camera.K);
  EXPECT_EQ(back.camera.distortion, config.camera.distortion);
  EXPECT_EQ(back.working_distance_mm, config.working_distance_mm);
  EXPECT_EQ(back.flashes.positions_mm, config.flashes.positions_mm);
}

const std::vector<std::string> kAllMfcKeys = {"working_distance_mm", "flashes.ring_radius_mm",
                                              "flashes.first_angle_deg", "flashes.step_deg", "flashes.plane_z_mm"};

}  // namespace

TEST(CalibrationImport, OpenCvSampleFile) {
  const fs::path file = kForeign / "opencv_sample.yml";
  const CalibrationImport imp = import_calibration(file);
  EXPECT_EQ(imp.source.format, ForeignFormat::opencv);
  const PinholeCamera& c = imp.config.camera;
  EXPECT_EQ(c.image_size, cv::Size(1280, 960));
  // The file's decimal text, read exactly.
  EXPECT_EQ(c.K, cv::Matx33d(1.4088460733653735e+03, 0., 6.4911805288526580e+02, 0., 1.4126119044320831e+03,
                             4.7972258579418383e+02, 0., 0., 1.));
  EXPECT_EQ(c.distortion, (std::vector<double>{-2.2821663204838516e-01, 3.0454966862063526e-01, 7.6327851382786463e-04,
                                               -5.3217688428079375e-04, 0.}));
  EXPECT_EQ(imp.source.distortion_model, "OpenCV, 5 coefficients");
  EXPECT_EQ(imp.source.keys_read,
            (std::vector<std::string>{"image_width", "image_height", "camera_matrix", "distortion_coefficients"}));
  EXPECT_EQ(
      imp.source.keys_unused,
      (std::vector<std::string>{"calibration_time", "nframes", "board_width", "board_height", "square_size", "flags",
                                "avg_reprojection_error", "per_view_reprojection_errors", "extrinsic_parameters"}));
  ASSERT_EQ(imp.source.notes.size(), 1u);
  EXPECT_EQ(imp.source.notes[0], "avg_reprojection_error 0.1332768878 px over 6 views (as the file states)");
  // No option, no base: every MFC key is the documented default.
  EXPECT_EQ(imp.defaults_used(), kAllMfcKeys);
  EXPECT_EQ(imp.config.working_distance_mm, 300.0);
  ASSERT_TRUE(imp.config.flashes.ring.has_value());
  EXPECT_EQ(imp.config.flashes.ring->radius_mm, 40.0);
  EXPECT_EQ(imp.config.flashes.ring->first_angle_deg, 0.0);
  EXPECT_EQ(imp.config.flashes.ring->step_deg, 45.0);
  EXPECT_EQ(imp.config.flashes.ring->plane_z_mm, 0.0);
  EXPECT_EQ(imp.config.flashes.positions_mm.size(), 8u);
  EXPECT_FALSE(imp.config.hand_eye.has_value());
  const std::string s = imp.summary(file);
  EXPECT_NE(s.find("read " + file.string() + " as an OpenCV calibration sample file"), std::string::npos) << s;
  EXPECT_NE(s.find("working_distance_mm: 300 mm (default)"), std::string::npos) << s;
  EXPECT_NE(s.find("flashes.step_deg: 45 deg (default)"), std::string::npos) << s;
  EXPECT_NE(s.find("not used: calibration_time, nframes,"), std::string::npos) << s;
  expect_round_trip(imp.config, fresh_dir("sample"));
}

TEST(CalibrationImport, OpenCvTutorialFiles) {
  // OpenCV 4.x: fisheye_model 0 is read, the flags comment is not a key.
  const CalibrationImport imp = import_calibration(kForeign / "opencv_tutorial.yml");
  EXPECT_EQ(imp.source.format, ForeignFormat::opencv);
  EXPECT_EQ(imp.config.camera.image_size, cv::Size(1280, 960));
  EXPECT_EQ(imp.config.camera.K, cv::Matx33d(1.4224610307306334e+03, 0., 6.3950000000000000e+02, 0.,
                                             1.4224610307306334e+03, 4.7950000000000000e+02, 0., 0., 1.));
  EXPECT_EQ(imp.config.camera.distortion,
            (std::vector<double>{-2.6324461818252320e-01, 1.2052985438724080e+00, 0., 0., -2.3413489320579797e+00}));
  EXPECT_TRUE(contains(imp.source.keys_read, "fisheye_model"));
  EXPECT_TRUE(contains(imp.source.keys_unused, "fix_aspect_ratio"));
  EXPECT_TRUE(contains(imp.source.keys_unused, "nr_of_frames"));
  EXPECT_EQ(imp.source.notes.at(0), "avg_reprojection_error 0.1558792797 px over 4 views (as the file states)");
  expect_round_trip(imp.config, fresh_dir("tutorial"));

  // OpenCV 2.x: the same calibration under capitalised keys, three-digit exponents.
  const CalibrationImport old = import_calibration(kForeign / "opencv_tutorial_2x.yml");
  EXPECT_EQ(old.config.camera.K, imp.config.camera.K);
  EXPECT_EQ(old.config.camera.distortion, imp.config.camera.distortion);
  EXPECT_EQ(old.config.camera.image_size, cv::Size(1280, 960));
  EXPECT_EQ(old.source.keys_read,
            (std::vector<std::string>{"image_Width", "image_Height", "Camera_Matrix", "Distortion_Coefficients"}));
  EXPECT_EQ(old.source.notes.at(0), "Avg_Reprojection_Error 0.1558792797 px over 4 views (as the file states)");
}

TEST(CalibrationImport, RosCameraInfoFiles) {
  const cv::Matx33d K(1408.8460733653735, 0, 649.1180528852658, 0, 1412.6119044320831, 479.72258579418383, 0, 0, 1);
  const std::vector<double> plumb_bob{-0.22821663204838516, 0.30454966862063526, 0.00076327851382786463,
                                      -0.00053217688428079375, 0};

  const CalibrationImport imp = import_calibration(kForeign / "ros_plumb_bob.yaml");
  EXPECT_EQ(imp.source.format, ForeignFormat::ros);
  EXPECT_EQ(imp.source.distortion_model, "plumb_bob");
  EXPECT_EQ(imp.config.camera.image_size, cv::Size(1280, 960));
  EXPECT_EQ(imp.config.camera.K, K);  // K, not the projection matrix's rectified focal lengths
  EXPECT_EQ(imp.config.camera.distortion, plumb_bob);
  EXPECT_EQ(imp.source.keys_read, (std::vector<std::string>{"image_width", "image_height", "camera_matrix",
                                                            "distortion_model", "distortion_coefficients"}));
  EXPECT_EQ(imp.source.keys_unused,
            (std::vector<std::string>{"camera_name", "rectification_matrix", "projection_matrix"}));
  EXPECT_EQ(imp.source.notes, (std::vector<std::string>{"camera_name 'mfc_camera'"}));
  EXPECT_EQ(imp.defaults_used(), kAllMfcKeys);
  EXPECT_NE(imp.summary("x.yaml").find("read x.yaml as a ROS camera_info file"), std::string::npos);
  expect_round_trip(imp.config, fresh_dir("ros"));

  // rational_polynomial: OpenCV's 8-coefficient model, which the camera file holds as it is.
  const CalibrationImport rational = import_calibration(kForeign / "ros_rational_polynomial.yaml");
  EXPECT_EQ(rational.source.distortion_model, "rational_polynomial");
  std::vector<double> eight = plumb_bob;
  eight[4] = 0.012904000000000001;
  eight.insert(eight.end(), {0.0004417, 0.061193499999999998, 0.0080999999999999996});
  EXPECT_EQ(rational.config.camera.distortion, eight);
  expect_round_trip(rational.config, fresh_dir("ros-rational"));

  // cameracalibrator.py's ost.yaml: numpy's layout over several lines, 5 decimals in K.
  const CalibrationImport ost = import_calibration(kForeign / "ros_ost.yaml");
  EXPECT_EQ(ost.source.format, ForeignFormat::ros);
  EXPECT_EQ(ost.config.camera.K, cv::Matx33d(1408.84607, 0, 649.11805, 0, 1412.6119, 479.72259, 0, 0, 1));
  EXPECT_EQ(ost.config.camera.distortion, (std::vector<double>{-0.228217, 0.304550, 0.000763, -0.000532, 0}));
  EXPECT_EQ(ost.source.notes, (std::vector<std::string>{"camera_name 'narrow_stereo'"}));

  // A stereo pair's camera: R is not the identity; K and D are still the unrectified image's.
  const fs::path dir = fresh_dir("ros-stereo");
  const std::string text = slurp(kForeign / "ros_plumb_bob.yaml");
  const CalibrationImport stereo =
      import_calibration(write(dir / "left.yaml", edited(text, "data: [1, 0, 0, 0, 1, 0, 0, 0, 1]",
                                                         "data: [0.9999, 0.0141, 0, -0.0141, 0.9999, 0, 0, 0, 1]")));
  EXPECT_EQ(stereo.config.camera.K, K);
  ASSERT_EQ(stereo.source.notes.size(), 2u);
  EXPECT_NE(stereo.source.notes[1].find("rectification_matrix is not the identity"), std::string::npos);

  // No distortion_model: plumb_bob, as camera_calibration_parsers assumes.
  const CalibrationImport old =
      import_calibration(write(dir / "old.yaml", edited(text, "distortion_model: plumb_bob\n", "")));
  EXPECT_EQ(old.config.camera.distortion, plumb_bob);
  EXPECT_EQ(old.source.notes.at(0), "no distortion_model: plumb_bob assumed (as camera_calibration_parsers does)");
}

TEST(CalibrationImport, MfcKeysFromOptionsAndBaseFile) {
  const fs::path dir = fresh_dir("mfc-keys");
  MfcKeyOptions o;
  o.working_distance_mm = 412.5;
  o.ring_radius_mm = 55;
  o.first_angle_deg = 22.5;
  o.step_deg = -45;
  o.plane_z_mm = 6;
  const CalibrationImport imp = import_calibration(kForeign / "ros_plumb_bob.yaml", o);
  EXPECT_TRUE(imp.defaults_used().empty());
  EXPECT_EQ(imp.config.working_distance_mm, 412.5);
  ASSERT_TRUE(imp.config.flashes.ring.has_value());
  EXPECT_EQ(imp.config.flashes.ring->radius_mm, 55);
  EXPECT_EQ(imp.config.flashes.positions_mm, FlashRing::regular({55, 22.5, -45, 6, 8}).positions_mm);
  EXPECT_NE(imp.summary("x.yaml").find("flashes.ring_radius_mm: 55 mm (given)"), std::string::npos);
  expect_round_trip(imp.config, dir);

  // A base camera file with measured LEDs and a hand-eye section: kept; one option still wins.
  CameraConfig base = load_camera_config(MFC_SOURCE_DIR "/config/camera-sim.yaml");
  base.working_distance_mm = 350;
  base.flashes = FlashRing{};
  for (int i = 0; i < 8; ++i) base.flashes.positions_mm.emplace_back(30 + i, -i, 2.5);
  HandEye he;
  he.mode = HandEye::Mode::eye_to_hand;
  he.camera_pose = cv::Matx44d(0, 1, 0, 10, -1, 0, 0, 20, 0, 0, 1, 900, 0, 0, 0, 1);
  base.hand_eye = he;
  save_camera_config(base, dir / "base.yaml");
  MfcKeyOptions b;
  b.base_camera_file = dir / "base.yaml";
  b.working_distance_mm = 333;
  const CalibrationImport merged = import_calibration(kForeign / "opencv_sample.yml", b);
  EXPECT_TRUE(merged.defaults_used().empty());
  EXPECT_EQ(merged.config.working_distance_mm, 333);
  EXPECT_FALSE(merged.config.flashes.ring.has_value());
  EXPECT_EQ(merged.config.flashes.positions_mm, base.flashes.positions_mm);
  ASSERT_TRUE(merged.config.hand_eye.has_value());
  EXPECT_EQ(merged.config.hand_eye->camera_pose, he.camera_pose);
  EXPECT_EQ(merged.config.camera.K(0, 0), 1.4088460733653735e+03);
  const std::string s = merged.summary("x.yaml");
  const std::string positions = "flashes.positions_mm: 8 measured LED positions (from " + (dir / "base.yaml").string();
  EXPECT_NE(s.find(positions + ")"), std::string::npos) << s;
  EXPECT_NE(s.find("hand_eye: kept;"), std::string::npos) << s;

  // A base with a ring: the ring keys not given come from it, not from the defaults.
  MfcKeyOptions r;
  r.base_camera_file = MFC_SOURCE_DIR "/config/camera-sim.yaml";
  r.plane_z_mm = 4;
  const CalibrationImport ring = import_calibration(kForeign / "opencv_sample.yml", r);
  EXPECT_TRUE(ring.defaults_used().empty());
  EXPECT_EQ(ring.config.flashes.ring->plane_z_mm, 4);
  EXPECT_EQ(ring.mfc_keys.at(1).key, "flashes.ring_radius_mm");
  EXPECT_EQ(ring.mfc_keys.at(1).from, MfcKeySource::From::base);

  // Options out of range are refused naming the camera key.
  const auto refused = [&](MfcKeyOptions bad) {
    return refusal([&] { import_calibration(kForeign / "opencv_sample.yml", bad); });
  };
  MfcKeyOptions bad;
  bad.working_distance_mm = 0;
  EXPECT_EQ(refused(bad), "key 'working_distance_mm': must be in (0, 100000] mm, got 0");
  bad = {};
  bad.ring_radius_mm = 1500;
  EXPECT_EQ(refused(bad), "key 'flashes.ring_radius_mm': must be in (0, 1000] mm, got 1500");
  bad = {};
  bad.step_deg = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(refused(bad), "key 'flashes.step_deg': must be in finite degrees, got nan");
  bad = {};
  bad.plane_z_mm = 300;  // LEDs at the default working distance
  EXPECT_NE(refused(bad).find("key 'flashes': LED behind the working distance"), std::string::npos) << refused(bad);
}

// Every refusal names the file and the key, and says why.
TEST(CalibrationImport, Refusals) {
  const fs::path dir = fresh_dir("refusals");
  const std::string opencv = slurp(kForeign / "opencv_sample.yml");
  const std::string ros = slurp(kForeign / "ros_plumb_bob.yaml");
  // The intrinsics as the two files write them.
  const std::string cv_k =
      "   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1.4088460733653735e+03, 0., "
      "6.4911805288526580e+02, 0.,\n       1.4126119044320831e+03, 4.7972258579418383e+02, "
      "0., 0., 1. ]\n";
  const std::string cv_d =
      "   rows: 5\n   cols: 1\n   dt: d\n   data: [ -2.2821663204838516e-01, "
      "3.0454966862063526e-01,\n       7.6327851382786463e-04, -5.3217688428079375e-04, 0. ]\n";
  const std::string ros_k =
      "  rows: 3\n  cols: 3\n  data: [1408.8460733653735, 0, 649.1180528852658, 0, "
      "1412.6119044320831, 479.72258579418383, 0, 0, 1]\n";
  const std::string ros_d =
      "  rows: 1\n  cols: 5\n  data: [-0.22821663204838516, 0.30454966862063526, "
      "0.00076327851382786463, -0.00053217688428079375, 0]\n";
  int n = 0;
  const auto refused = [&](const std::string& text) {
    const fs::path f = write(dir / ("case-" + std::to_string(n++) + ".yaml"), text);
    return refusal([&] { read_foreign_calibration(f); });
  };
  // "<the last case's file>:<line>: "
  const auto at = [&](int line) {
    return (dir / ("case-" + std::to_string(n - 1) + ".yaml")).string() + ":" + std::to_string(line) + ": ";
  };

  // Fisheye, in both formats.
  EXPECT_EQ(refusal([&] { read_foreign_calibration(kForeign / "opencv_tutorial_fisheye.yml"); }),
            (kForeign / "opencv_tutorial_fisheye.yml").string() +
                ":12: key 'fisheye_model': fisheye lenses are not supported (mfcd's camera model is the "
                "pinhole with polynomial distortion)");
  EXPECT_EQ(refusal([&] { read_foreign_calibration(kForeign / "ros_equidistant.yaml"); }),
            (kForeign / "ros_equidistant.yaml").string() +
                ":8: key 'distortion_model': 'equidistant': fisheye lenses are not supported (mfcd's camera "
                "model is the pinhole with polynomial distortion)");

  // camera_matrix missing, not 3x3, data of the wrong length, not [fx s cx; 0 fy cy; 0 0 1], dt.
  std::string msg = refused(edited(opencv, "camera_matrix: !!opencv-matrix\n" + cv_k, ""));
  EXPECT_EQ(msg, at(3) +
                     "key 'camera_matrix': missing (neither an OpenCV calibration nor a ROS camera_info file "
                     "has been recognised)");
  msg = refused(edited(ros, "camera_matrix:\n" + ros_k, ""));
  EXPECT_EQ(msg, at(1) + "key 'camera_matrix': missing");
  const std::string ros_k_3x4 =
      "  rows: 3\n  cols: 4\n  data: [1408.8460733653735, 0, 649.1180528852658, 0, 0, "
      "1412.6119044320831, 479.72258579418383, 0, 0, 0, 1, 0]\n";
  msg = refused(edited(ros, ros_k, ros_k_3x4));
  EXPECT_EQ(msg, at(5) + "key 'camera_matrix': a 3x4 matrix, expected 3x3");
  msg = refused(edited(ros, ros_k, edited(ros_k_3x4, "cols: 4", "cols: 3")));
  EXPECT_EQ(msg, at(7) + "key 'camera_matrix': 'data' must list rows x cols = 3 x 3 = 9 numbers, it lists 12");
  msg = refused(edited(opencv, cv_k,
                       "   rows: 2\n   cols: 2\n   dt: d\n   data: [ 1.4088460733653735e+03, 0., 0., "
                       "1.4126119044320831e+03 ]\n"));
  EXPECT_EQ(msg, at(11) + "key 'camera_matrix': a 2x2 matrix, expected 3x3");
  msg = refused(edited(ros, "479.72258579418383, 0, 0, 1]", "479.72258579418383, 0, 0, 0.5]"));
  EXPECT_EQ(msg, at(5) + "key 'camera_matrix': not of the form [fx s cx; 0 fy cy; 0 0 1]");
  msg = refused(edited(opencv, cv_k, edited(cv_k, "dt: d", "dt: \"2d\"")));
  EXPECT_EQ(msg, at(14) + "key 'camera_matrix': expected 'dt' to be one number per element (d, f, ...), got '2d'");

  // Focal lengths: zero, negative, not finite (FileStorage writes .Nan and .Inf), not a number.
  msg = refused(edited(ros, "data: [1408.8460733653735,", "data: [0,"));
  EXPECT_EQ(msg, at(5) +
                     "key 'camera_matrix': the focal lengths must be positive, got fx = 0 (entry (0, 0)), "
                     "fy = 1412.6119044320831 (entry (1, 1))");
  msg = refused(edited(opencv, "1.4126119044320831e+03,", "-1.4126119044320831e+03,"));
  EXPECT_EQ(msg, at(11) +
                     "key 'camera_matrix': the focal lengths must be positive, got fx = 1.4088460733653735e+03 "
                     "(entry (0, 0)), fy = -1.4126119044320831e+03 (entry (1, 1))");
  msg = refused(edited(opencv, "[ 1.4088460733653735e+03,", "[ .Nan,"));
  EXPECT_EQ(msg, at(11) + "key 'camera_matrix': entry (0, 0) is not finite (.Nan)");
  msg = refused(edited(ros, "1412.6119044320831, 479", "-.inf, 479"));
  EXPECT_EQ(msg, at(5) + "key 'camera_matrix': entry (1, 1) is not finite (-.inf)");
  msg = refused(edited(ros, "data: [1408.8460733653735,", "data: [fx,"));
  EXPECT_EQ(msg, at(7) + "key 'camera_matrix': expected a number, got 'fx'");

  // Image size: missing, zero, negative, not an integer, too large.
  msg = refused(edited(opencv, "image_width: 1280\n", ""));
  EXPECT_EQ(msg, at(3) + "key 'image_width': missing");
  msg = refused(edited(ros, "image_height: 960", "image_height: 0"));
  EXPECT_EQ(msg, at(2) + "key 'image_height': must be in 1..20000 pixels, got 0");
  msg = refused(edited(opencv, "image_width: 1280", "image_width: -1280"));
  EXPECT_EQ(msg, at(5) + "key 'image_width': must be in 1..20000 pixels, got -1280");
  msg = refused(edited(ros, "image_width: 1280", "image_width: 1280.5"));
  EXPECT_EQ(msg, at(1) + "key 'image_width': expected an integer, got '1280.5'");
  msg = refused(edited(ros, "image_width: 1280", "image_width: 40000"));
  EXPECT_EQ(msg, at(1) + "key 'image_width': must be in 1..20000 pixels, got 40000");

  // Coefficients: counts the model does not have, shape, not finite, model, missing.
  msg = refused(edited(opencv, cv_d, edited(edited(cv_d, "rows: 5", "rows: 6"), "0. ]", "0., 0. ]")));
  EXPECT_EQ(msg, at(17) +
                     "key 'distortion_coefficients': 6 coefficients; OpenCV's pinhole models have 4, 5, 8, 12 "
                     "or 14 (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4 [tx ty]]]])");
  msg =
      refused(edited(opencv, cv_d, edited(edited(cv_d, "rows: 5\n   cols: 1", "rows: 2\n   cols: 2"), ", 0. ]", " ]")));
  EXPECT_EQ(msg, at(17) + "key 'distortion_coefficients': a 2x2 matrix, expected one row or one column");
  msg = refused(edited(ros, ros_d, edited(edited(ros_d, "cols: 5", "cols: 4"), ", 0]", "]")));
  EXPECT_EQ(msg, at(10) + "key 'distortion_coefficients': plumb_bob has 5 coefficients (k1 k2 t1 t2 k3), got 4");
  msg = refused(edited(ros, ros_d, "  rows: 1\n  cols: 0\n  data: []\n"));
  EXPECT_EQ(msg, at(10) + "key 'distortion_coefficients': plumb_bob has 5 coefficients (k1 k2 t1 t2 k3), got 0");
  msg = refused(edited(ros, "distortion_model: plumb_bob", "distortion_model: rational_polynomial"));
  EXPECT_EQ(msg, at(10) +
                     "key 'distortion_coefficients': rational_polynomial has 8 coefficients (k1 k2 t1 t2 k3 k4 "
                     "k5 k6), got 5");
  msg = refused(edited(ros, "-0.00053217688428079375, 0]", "-0.00053217688428079375, .nan]"));
  EXPECT_EQ(msg, at(10) + "key 'distortion_coefficients': coefficient 4 is not finite (.nan)");
  msg = refused(edited(ros, "distortion_model: plumb_bob", "distortion_model: kannala_brandt"));
  EXPECT_EQ(msg, at(8) +
                     "key 'distortion_model': 'kannala_brandt' is not imported (plumb_bob and rational_polynomial "
                     "are)");
  msg = refused(edited(opencv, "distortion_coefficients: !!opencv-matrix", "distortion: !!opencv-matrix"));
  EXPECT_EQ(msg, at(3) + "key 'distortion_coefficients': missing");

  // Files that are not a calibration to import.
  msg = refused("<?xml version=\"1.0\"?>\n<opencv_storage>\n<image_width>1280</image_width>\n");
  EXPECT_EQ(msg, (dir / ("case-" + std::to_string(n - 1) + ".yaml")).string() +
                     ": an XML file; only YAML is imported (OpenCV's calibration samples write YAML when the output "
                     "file name ends in .yml or .yaml)");
  msg = refused("image_width: 1280\ncamera_matrix: [1, 2\n");
  EXPECT_NE(msg.find(at(3) + "not valid YAML: "), std::string::npos) << msg;
  msg = refused("");
  EXPECT_NE(msg.find(": not a calibration file (the top level is not a mapping of keys)"), std::string::npos) << msg;
  msg = refusal([] { read_foreign_calibration(MFC_SOURCE_DIR "/config/camera-sim.yaml"); });
  EXPECT_EQ(msg, std::string(MFC_SOURCE_DIR "/config/camera-sim.yaml") +
                     ": already a camera file of this project (it has 'working_distance_mm'): use it as it is, "
                     "nothing to import");
  msg = refusal([&] { read_foreign_calibration(dir / "absent.yml"); });
  EXPECT_EQ(msg, (dir / "absent.yml").string() + ": cannot open the calibration file");

  // import_calibration refuses the same way (and so writes nothing).
  msg = refusal([&] { import_calibration(kForeign / "ros_equidistant.yaml"); });
  EXPECT_NE(msg.find("fisheye lenses are not supported"), std::string::npos) << msg;
}
