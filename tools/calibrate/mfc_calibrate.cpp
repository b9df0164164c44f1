// mfc-calibrate: camera intrinsics and hand-eye calibration (docs/calibration.md).
//
//   mfc-calibrate intrinsics (--images DIR | --sim N) --board 9x6 --square-mm S --out CAM.yaml [--apply]
//   mfc-calibrate hand-eye --mode eye-in-hand|eye-to-hand --camera CAM.yaml (--views LIST.yaml | --sim N)
//                 --board 9x6 --square-mm S --out CAM.yaml [--apply]
//   mfc-calibrate rollback --out CAM.yaml
//   mfc-calibrate import FILE --out CAM.yaml [--camera BASE.yaml] [--working-distance MM]
//                 [--flash-ring-radius MM] [--flash-first-angle DEG] [--flash-step DEG]
//                 [--flash-plane-z MM] [--apply]
//
// Prints the figures; writes CAM.yaml (atomically, keeping CAM.yaml.previous) only with --apply,
// otherwise shows what it would write; import writes a CAM.yaml that does not exist yet without
// --apply. Exit status: 0 done, 1 calibration failed or file refused, 2 usage.
#include "tools/common/cli.hpp"
#include "vision/calib/calibration_import.hpp"
#include "vision/calib/hand_eye.hpp"
#include "vision/calib/intrinsics.hpp"
#include "vision/calib/sim_board.hpp"
#include "vision/calib/store.hpp"

#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <optional>
#include <random>
#include <sstream>

using namespace mfcd::vision;
using namespace mfcd::vision::calib;
namespace fs = std::filesystem;

namespace {

ViewReport unreadable(const std::string& label) {
  ViewReport r;
  r.label = label;
  r.reason = "cannot read image";
  return r;
}

using mfcd::tools::UsageError;

struct Args {
  std::string command;
  std::vector<std::string> positional;  // import's FILE
  std::map<std::string, std::string> values;
  bool apply = false;

  bool has(const std::string& k) const { return values.count(k) != 0; }
  std::string get(const std::string& k, const std::string& def = {}) const {
    const auto it = values.find(k);
    return it == values.end() ? def : it->second;
  }
  std::string need(const std::string& k) const {
    if (!has(k)) throw UsageError("missing --" + k);
    return get(k);
  }
  double number(const std::string& k, double def) const {
    if (!has(k)) return def;
    try {
      size_t used = 0;
      const double v = std::stod(get(k), &used);
      if (used != get(k).size()) throw std::invalid_argument("trailing characters");
      return v;
    } catch (const std::exception&) {
      throw UsageError("--" + k + " '" + get(k) + "': expected a number");
    }
  }
};

// `--KEY VALUE` of a subcommand, kept as text in a.values: each command reads and checks its
// values where it uses them (Args::number words a bad number).
void add_value(CLI::App& cmd, Args& a, const std::string& key, const std::string& type, const std::string& help) {
  cmd.add_option_function<std::string>(
         "--" + key, [&a, key](const std::string& v) { a.values[key] = v; }, help)
      ->type_name(type);
}

void add_board_options(CLI::App& cmd, Args& a) {
  add_value(cmd, a, "board", "CxR", "inner corners, columns x rows (default 9x6)");
  add_value(cmd, a, "square-mm", "MM", "square size (default 10)");
}

void add_sim_options(CLI::App& cmd, Args& a, const std::string& saved) {
  add_value(cmd, a, "sim", "N",
            "render N views of the plate in the simulated cell (--camera or\n"
            "config/camera-sim.yaml is the true camera); prints the errors");
  add_value(cmd, a, "save-views", "DIR", "keep the simulated images (" + saved + ")");
  add_value(cmd, a, "seed", "N", "seed of the simulated views (default 1)");
}

void add_apply_flag(CLI::App& cmd, Args& a, const std::string& help) { cmd.add_flag("--apply", a.apply, help); }

// The subcommands and their options (docs/calibration.md).
void add_commands(CLI::App& app, Args& a) {
  const std::string apply = "write CAM.yaml (keeping CAM.yaml.previous); without it, show what would be written";
  CLI::App* intrinsics = app.add_subcommand("intrinsics", "camera intrinsics from checkerboard images");
  add_value(*intrinsics, a, "images", "DIR", "images of the board (png, jpg, bmp, tif)");
  add_sim_options(*intrinsics, a, "view-NN.png");
  add_board_options(*intrinsics, a);
  add_value(*intrinsics, a, "distortion", "MODEL", "none|radial|radial-tangential|full (default radial)");
  add_value(*intrinsics, a, "camera", "BASE.yaml",
            "the camera file the result is merged into (default: CAM.yaml\n"
            "when it exists, else config/camera-sim.yaml)");
  add_value(*intrinsics, a, "out", "CAM.yaml", "the camera file to write");
  add_apply_flag(*intrinsics, a, apply);

  CLI::App* hand_eye = app.add_subcommand("hand-eye", "the hand-eye transform from board views with robot poses");
  add_value(*hand_eye, a, "mode", "MODE", "eye-in-hand|eye-to-hand");
  add_value(*hand_eye, a, "camera", "CAM.yaml", "the calibrated camera");
  add_value(*hand_eye, a, "views", "LIST.yaml", "the views and their flange poses (below)");
  add_sim_options(*hand_eye, a, "pose-NN.png and views.yaml");
  add_board_options(*hand_eye, a);
  add_value(*hand_eye, a, "out", "CAM.yaml", "the camera file to write");
  add_apply_flag(*hand_eye, a, apply);
  add_value(*hand_eye, a, "check", "IMAGE", "a view in one more robot pose: predicted vs seen board");
  add_value(*hand_eye, a, "check-pose", "x,y,z,rx,ry,rz", "its flange pose (mm, degrees)");
  hand_eye->footer(
      "LIST.yaml (OpenCV YAML): views: [ { image: v00.png, pose: [x, y, z, rx, ry, rz] }, ... ]\n"
      "  pose: robot flange in the base frame, mm and degrees, R = Rz(rz) Ry(ry) Rx(rx);\n"
      "  image paths relative to LIST.yaml.");

  CLI::App* rollback =
      app.add_subcommand("rollback", "restore CAM.yaml.previous (the replaced file becomes the previous one)");
  add_value(*rollback, a, "out", "CAM.yaml", "the camera file to restore");

  CLI::App* import = app.add_subcommand("import", "a camera file from an OpenCV or ROS calibration file");
  import->add_option("FILE", a.positional, "an OpenCV calibration sample's YAML or a ROS camera_info YAML")
      ->type_name("");
  add_value(*import, a, "out", "CAM.yaml", "the camera file to write (a new one is written without --apply)");
  add_value(*import, a, "camera", "BASE.yaml",
            "where the MFC keys FILE lacks come from (default: CAM.yaml when it exists)");
  add_value(*import, a, "working-distance", "MM", "working_distance_mm (default 300)");
  add_value(*import, a, "flash-ring-radius", "MM", "flashes.ring_radius_mm (default 40)");
  add_value(*import, a, "flash-first-angle", "DEG", "flashes.first_angle_deg (default 0)");
  add_value(*import, a, "flash-step", "DEG", "flashes.step_deg (default 45)");
  add_value(*import, a, "flash-plane-z", "MM", "flashes.plane_z_mm (default 0)");
  add_apply_flag(*import, a, "replace an existing CAM.yaml (keeping CAM.yaml.previous)");
  import->footer("The MFC keys FILE lacks come from the options, else from BASE.yaml, else from the defaults.");
  app.require_subcommand(1);
}

CheckerBoard board_of(const Args& a) {
  const cv::Size s = parse_pattern_size(a.get("board", "9x6"));
  CheckerBoard b{s.width, s.height, a.number("square-mm", 10.0)};
  b.validate();
  return b;
}

int count_of(const Args& a, const std::string& key) {
  const double n = a.number(key, 0);
  if (n < 1 || n > 500 || n != std::floor(n)) throw UsageError("--" + key + ": expected a count 1..500");
  return static_cast<int>(n);
}

RobotPose parse_pose(const std::string& text, const std::string& where) {
  std::vector<double> v;
  std::stringstream s(text);
  std::string item;
  while (std::getline(s, item, ',')) {
    try {
      v.push_back(std::stod(item));
    } catch (const std::exception&) {
      throw UsageError(where + ": '" + text + "' is not x,y,z,rx,ry,rz");
    }
  }
  if (v.size() != 6) throw UsageError(where + ": expected 6 numbers x,y,z,rx,ry,rz, got " + std::to_string(v.size()));
  return {v[0], v[1], v[2], v[3], v[4], v[5]};
}

fs::path sim_camera_file(const Args& a) {
  return a.has("camera") ? fs::path(a.get("camera")) : fs::path(MFC_SOURCE_DIR "/config/camera-sim.yaml");
}

// The configuration the result is merged into: --camera, else the current --out, else the
// simulated camera's file (flashes and working distance are not calibrated here).
CameraConfig base_config(const Args& a) {
  if (a.has("camera")) return load_camera_config(a.get("camera"));
  if (fs::exists(a.need("out"))) return load_camera_config(a.get("out"));
  return load_camera_config(MFC_SOURCE_DIR "/config/camera-sim.yaml");
}

// Shows or writes the new configuration.
int finish(const Args& a, const CameraConfig& config) {
  const fs::path out = a.need("out");
  if (!a.apply) {
    const fs::path tmp = fs::temp_directory_path() / ("mfc-calibrate-preview-" + std::to_string(::getpid()) + ".yaml");
    save_camera_config(config, tmp);
    std::ifstream f(tmp);
    std::cout << "\nwould write " << out << " (run again with --apply to write it):\n" << f.rdbuf();
    fs::remove(tmp);
    return 0;
  }
  CalibrationStore store(out);
  store.apply(config);
  std::cout << "\nwrote " << out;
  if (fs::exists(store.previous_file())) std::cout << " (previous kept as " << store.previous_file() << ")";
  std::cout << '\n';
  return 0;
}

void save_image(const fs::path& dir, const std::string& name, const cv::Mat& img) {
  fs::create_directories(dir);
  if (!cv::imwrite((dir / name).string(), img))
    throw std::runtime_error((dir / name).string() + ": cannot write image");
}

int run_intrinsics(const Args& a) {
  const CheckerBoard board = board_of(a);
  IntrinsicsOptions opt;
  opt.distortion = parse_distortion_model(a.get("distortion", "radial"));
  IntrinsicsCalibration cal(board, opt);
  std::cout << "board: " << board.describe() << '\n';
  if (a.has("images") == a.has("sim")) throw UsageError("give exactly one of --images DIR, --sim N");
  std::optional<PinholeCamera> truth;
  if (a.has("images")) {
    const fs::path dir = a.get("images");
    if (!fs::is_directory(dir)) throw UsageError("--images " + dir.string() + ": not a directory");
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(dir)) {
      std::string ext = e.path().extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
      if (ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".bmp" || ext == ".tif" || ext == ".tiff")
        files.push_back(e.path());
    }
    std::sort(files.begin(), files.end());
    if (files.empty()) throw UsageError("--images " + dir.string() + ": no images (png, jpg, bmp, tif)");
    for (const auto& f : files) {
      const cv::Mat img = cv::imread(f.string(), cv::IMREAD_GRAYSCALE);
      const ViewReport v = img.empty() ? unreadable(f.filename()) : cal.add_view(img, f.filename());
      std::cout << "  " << f.filename().string() << ": " << (v.accepted ? "board found" : v.reason) << '\n';
    }
  } else {
    const int n = count_of(a, "sim");
    const CameraConfig sim = load_camera_config(sim_camera_file(a));
    truth = sim.camera;
    SimBoardScene scene(sim, board);
    std::mt19937 rng(static_cast<uint32_t>(a.number("seed", 1)));
    const auto poses = random_board_views(scene, n, sim.working_distance_mm, rng, 60, 0.7, 1.1);
    for (size_t i = 0; i < poses.size(); ++i) {
      char name[32];
      std::snprintf(name, sizeof name, "view-%02zu.png", i);
      const cv::Mat1b img = scene.render(poses[i], 1000 + i);
      if (a.has("save-views")) save_image(a.get("save-views"), name, img);
      const ViewReport v = cal.add_view(img, name);
      std::cout << "  " << name << " (simulated): " << (v.accepted ? "board found" : v.reason) << '\n';
    }
  }
  const IntrinsicsResult r = cal.compute();
  std::cout << r.summary();
  if (truth) {
    std::printf("  vs the simulated camera: fx %+.3f%%  fy %+.3f%%  cx %+.3f%%  cy %+.3f%%\n",
                100 * (r.camera.fx() / truth->fx() - 1), 100 * (r.camera.fy() / truth->fy() - 1),
                100 * (r.camera.cx() / truth->cx() - 1), 100 * (r.camera.cy() / truth->cy() - 1));
  }
  return finish(a, with_intrinsics(base_config(a), r));
}

int run_hand_eye(const Args& a) {
  const CheckerBoard board = board_of(a);
  const HandEyeMode mode = parse_hand_eye_mode(a.need("mode"));
  const CameraConfig camera_cfg = load_camera_config(a.need("camera"));
  HandEyeCalibration cal(mode, camera_cfg.camera, board);
  std::cout << "board: " << board.describe() << ", " << to_string(mode) << '\n';
  if (a.has("views") == a.has("sim")) throw UsageError("give exactly one of --views LIST.yaml, --sim N");
  std::optional<SimHandEyeCell> cell;
  std::unique_ptr<SimBoardScene> scene;
  std::mt19937 rng(static_cast<uint32_t>(a.number("seed", 1)));
  if (a.has("views")) {
    const fs::path list = a.get("views");
    cv::FileStorage fs;
    try {
      if (!fs.open(list.string(), cv::FileStorage::READ)) throw UsageError(list.string() + ": cannot open");
    } catch (const cv::Exception& e) {
      throw UsageError(list.string() + ": not an OpenCV YAML file: " + e.what());
    }
    const cv::FileNode views = fs["views"];
    if (!views.isSeq()) throw UsageError(list.string() + ": key 'views': expected a sequence");
    int i = 0;
    for (const auto& v : views) {
      const std::string where = list.string() + ": views[" + std::to_string(i++) + "]";
      if (!v["image"].isString()) throw UsageError(where + ".image: missing");
      std::vector<double> p;
      v["pose"] >> p;
      if (p.size() != 6) throw UsageError(where + ".pose: expected [x, y, z, rx, ry, rz]");
      const fs::path img_path = list.parent_path() / static_cast<std::string>(v["image"]);
      const cv::Mat img = cv::imread(img_path.string(), cv::IMREAD_GRAYSCALE);
      const RobotPose pose{p[0], p[1], p[2], p[3], p[4], p[5]};
      const ViewReport r =
          img.empty() ? unreadable(img_path.filename()) : cal.add_view(img, pose, img_path.filename().string());
      std::cout << "  " << img_path.filename().string() << ": " << (r.accepted ? "board found" : r.reason) << '\n';
    }
  } else {
    const int n = count_of(a, "sim");
    scene = std::make_unique<SimBoardScene>(camera_cfg, board);
    cell = make_sim_hand_eye_cell(*scene, mode, n, camera_cfg.working_distance_mm, rng);
    cv::FileStorage list;
    if (a.has("save-views")) {
      fs::create_directories(a.get("save-views"));
      list.open((fs::path(a.get("save-views")) / "views.yaml").string(), cv::FileStorage::WRITE);
      list << "views"
           << "[";
    }
    for (size_t i = 0; i < cell->views.size(); ++i) {
      char name[32];
      std::snprintf(name, sizeof name, "pose-%02zu.png", i);
      const auto& v = cell->views[i];
      const cv::Mat1b img = scene->render(v.T_camera_board, 2000 + i);
      if (list.isOpened()) {
        save_image(a.get("save-views"), name, img);
        list << "{"
             << "image" << name << "pose" << std::vector<double>{v.flange.x_mm,   v.flange.y_mm,   v.flange.z_mm,
                                                                 v.flange.rx_deg, v.flange.ry_deg, v.flange.rz_deg}
             << "}";
      }
      const ViewReport r = cal.add_view(img, v.flange, name);
      std::printf("  %s (simulated) flange %.3f %.3f %.3f mm %.3f %.3f %.3f deg: %s\n", name, v.flange.x_mm,
                  v.flange.y_mm, v.flange.z_mm, v.flange.rx_deg, v.flange.ry_deg, v.flange.rz_deg,
                  r.accepted ? "board found" : r.reason.c_str());
    }
    if (list.isOpened()) list << "]";
  }
  const HandEyeResult r = cal.compute();
  std::cout << r.summary();
  if (cell) {
    std::printf("  vs the simulated cell: hand-eye %.4f mm %.5f deg, board %.4f mm %.5f deg\n",
                cv::norm(translation_of(r.hand_eye) - translation_of(cell->hand_eye_true)),
                rotation_angle_deg(rotation_of(r.hand_eye), rotation_of(cell->hand_eye_true)),
                cv::norm(translation_of(r.board) - translation_of(cell->board_true)),
                rotation_angle_deg(rotation_of(r.board), rotation_of(cell->board_true)));
    // Check step on one more simulated pose.
    const SimHandEyeCell more = make_sim_hand_eye_cell(*scene, mode, 1, camera_cfg.working_distance_mm, rng);
    std::cout << "  new pose "
              << cal.check(r, scene->render(more.views[0].T_camera_board, 99), more.views[0].flange.matrix()).summary();
  }
  if (a.has("check")) {
    const cv::Mat img = cv::imread(a.get("check"), cv::IMREAD_GRAYSCALE);
    if (img.empty()) throw UsageError("--check " + a.get("check") + ": cannot read image");
    const RobotPose pose = parse_pose(a.need("check-pose"), "--check-pose");
    std::cout << "  " << a.get("check") << ' ' << cal.check(r, img, pose.matrix()).summary();
  }
  // Merge into the file being calibrated when it exists (it may hold newer intrinsics).
  CameraConfig base = fs::exists(a.need("out")) ? load_camera_config(a.get("out")) : camera_cfg;
  return finish(a, with_hand_eye(base, r));
}

// import's option for each MFC key, to say how to set the ones that took their default.
const std::map<std::string, std::string> kMfcKeyOptions = {{"working_distance_mm", "--working-distance"},
                                                           {"flashes.ring_radius_mm", "--flash-ring-radius"},
                                                           {"flashes.first_angle_deg", "--flash-first-angle"},
                                                           {"flashes.step_deg", "--flash-step"},
                                                           {"flashes.plane_z_mm", "--flash-plane-z"}};

// A number option of import, checked against its range (the camera file's, docs/camera.md).
std::optional<double> import_option(const Args& a, const std::string& key, double lo, double hi, const char* range) {
  if (!a.has(key)) return std::nullopt;
  const double v = a.number(key, 0);
  if (!std::isfinite(v) || !(v > lo) || v > hi) throw UsageError("--" + key + " " + a.get(key) + ": must be " + range);
  return v;
}

int run_import(const Args& a) {
  if (a.positional.size() != 1) throw UsageError("import: give one calibration FILE (OpenCV or ROS YAML)");
  const fs::path file = a.positional[0];
  const fs::path out = a.need("out");
  std::error_code ec;
  if (fs::exists(out) && fs::equivalent(file, out, ec))
    throw UsageError("--out " + out.string() + " is the file being imported: give the camera file to write");
  const double inf = std::numeric_limits<double>::infinity();
  MfcKeyOptions o;
  o.working_distance_mm = import_option(a, "working-distance", 0, 1e5, "in (0, 100000] mm");
  o.ring_radius_mm = import_option(a, "flash-ring-radius", 0, 1000, "in (0, 1000] mm");
  o.first_angle_deg = import_option(a, "flash-first-angle", -inf, inf, "a finite angle in degrees");
  o.step_deg = import_option(a, "flash-step", -inf, inf, "a finite angle in degrees");
  o.plane_z_mm = import_option(a, "flash-plane-z", -inf, inf, "a finite length in mm");
  // The MFC keys not given are kept from the camera file being replaced, as intrinsics does.
  if (a.has("camera"))
    o.base_camera_file = a.get("camera");
  else if (fs::exists(out))
    o.base_camera_file = out;

  const CalibrationImport imp = import_calibration(file, o);
  std::cout << imp.summary(file);
  const std::vector<std::string> defaults = imp.defaults_used();
  std::cout << "defaults used:";
  if (defaults.empty()) std::cout << " none";
  for (size_t i = 0; i < defaults.size(); ++i) {
    const auto& k = defaults[i];
    const auto it = std::find_if(imp.mfc_keys.begin(), imp.mfc_keys.end(), [&](const auto& m) { return m.key == k; });
    std::cout << (i ? ", " : " ") << k << ' ' << it->value << " (" << kMfcKeyOptions.at(k) << ')';
  }
  std::cout << '\n';
  if (!defaults.empty())
    std::cout << "  measure them on the camera and import again with those options, or edit " << out.string()
              << " (docs/camera.md)\n";
  // A new file is written at once; replacing one needs --apply, like a calibration.
  Args write = a;
  write.apply = a.apply || !fs::exists(out);
  const int rc = finish(write, imp.config);
  if (write.apply) {
    const CameraConfig back = load_camera_config(out);
    if (back.camera.K != imp.config.camera.K || back.camera.distortion != imp.config.camera.distortion ||
        back.camera.image_size != imp.config.camera.image_size)
      throw std::runtime_error(out.string() + ": the intrinsics read back differ from the imported ones");
  }
  return rc;
}

int run_rollback(const Args& a) {
  CalibrationStore store(a.need("out"));
  store.rollback();
  std::cout << "restored " << store.file() << " from " << store.previous_file()
            << " (the replaced file is now the previous one)\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Camera intrinsics and hand-eye calibration (docs/calibration.md). Prints the figures; writes\n"
      "CAM.yaml (atomically, keeping CAM.yaml.previous) only with --apply, otherwise shows what it\n"
      "would write. Exit status: 0 done, 1 calibration failed or file refused, 2 usage.",
      "mfc-calibrate"};
  mfcd::tools::init_app(app);
  Args a;
  add_commands(app, a);
  if (const auto code = mfcd::tools::parse(app, argc, argv)) return *code;
  a.command = app.get_subcommands().front()->get_name();
  try {
    if (a.command == "import") return run_import(a);
    if (a.command == "intrinsics") return run_intrinsics(a);
    if (a.command == "hand-eye") return run_hand_eye(a);
    return run_rollback(a);
  } catch (const UsageError& e) {
    return mfcd::tools::usage_error(app, e.what());
  } catch (const CalibrationError& e) {
    std::cerr << "mfc-calibrate: " << e.what() << "\nnothing written\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "mfc-calibrate: " << e.what() << "\nnothing written\n";
    return 1;
  }
}
