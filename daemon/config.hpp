#pragma once
// mfcd's configuration: one YAML file (docs/configuration.md documents every key). Parsed and
// validated as a whole, at start and on SIGHUP; an error names the file, the line and the key.
// Relative paths are resolved against a search path (the config file's directory, --data-dir,
// the build tree for development runs, /var/lib/mfcd) and must exist.
#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "daemon/log.hpp"
#include "daemon/web_settings.hpp"
#include "motion/can_publisher.hpp"
#include "motion/modbus_server.hpp"
#include "motion/pick_choice.hpp"
#include "motion/pick_transform.hpp"
#include "vision/pipeline/bin_picking_pipeline.hpp"

namespace mfcd::daemon {

namespace fs = std::filesystem;

// A configuration error: `what()` is "<source>:<line>: <key>: <reason>".
class ConfigError : public std::runtime_error {
 public:
  ConfigError(std::string source, int line, std::string key, const std::string& reason);
  const std::string& source() const { return source_; }
  int line() const { return line_; }  // 1-based; 0 when the error is about the whole file
  const std::string& key() const { return key_; }

 private:
  std::string source_, key_;
  int line_;
};

enum class RunMode { Triggered, Continuous };
enum class CameraType { Simulated, V4L2, Aravis };
enum class LightsType { Simulated, Gpiod, Camera };
enum class StrobeSourceSetting { ExposureActive, Timer };

const char* to_string(RunMode m);

// Where the gripper takes a part (vision::GraspFeature): a spot in the part's model frame that
// must be on top and facing the camera for the pick to be worth trying (pick.weight_grasp,
// pick.min_grasp_visibility).
struct GraspFeatureSetting {
  double x_mm = 0, y_mm = 0, z_mm = 0;      // the spot's centre on the part's surface
  double radius_mm = 4;                     // the free disc the gripper needs around it
  std::array<double, 3> approach{0, 0, 0};  // direction the gripper comes from (out of the surface); 0 = any
  double max_tilt_deg = 60;                 // how far the approach may face away from the camera
};

struct RecipeConfig {
  int id = 0;                                       // the PLC's RECIPE_ID
  std::string part;                                 // part name (for logs, status, the simulated bin)
  int obj_id = 0;                                   // object id in the template file; 0 = every loaded part
  std::optional<fs::path> templates;                // .tdb (mfc-teach), resolved
  std::optional<fs::path> mesh;                     // STL for the simulated bin, resolved
  std::vector<GraspFeatureSetting> grasp_features;  // none: every candidate counts as graspable
};

struct CameraSettings {
  CameraType type = CameraType::Simulated;
  fs::path model;                      // camera YAML (intrinsics + flash ring, docs/camera.md), resolved
  std::string device = "/dev/video0";  // V4L2 node, or the Aravis camera id / IP address
  int bits_per_pixel = 8;
  int frame_rate = 0;
  std::optional<int> exposure_us;
  std::optional<double> gain;  // V4L2: an integer control value; Aravis: the camera's Gain unit (dB)
  int buffer_count = 4;
  int dequeue_timeout_ms = 1000;
  int packet_size = 0;            // Aravis, GigE Vision: stream packet size in bytes; 0 = Aravis's choice
  int simulated_exposure_us = 0;  // simulated camera: sleep this long per exposure
};

struct LightsSettings {
  LightsType type = LightsType::Simulated;
  std::string chip = "mfc-leds";
  std::array<unsigned, 8> offsets{0, 1, 2, 3, 4, 5, 6, 7};
  bool active_low = false;  // gpiod: lines; camera: the strobe line (LineInverter)
  // type camera: the LEDs are fired by the Aravis camera's outputs (docs/hal.md, "Camera strobe").
  std::string strobe_line = "Line1";
  std::array<std::string, 3> select_lines{"Line2", "Line3", "Line4"};  // LED index bit 0, 1, 2
  StrobeSourceSetting strobe_source = StrobeSourceSetting::ExposureActive;
  int strobe_pulse_us = 0;  // strobe_source timer: pulse length from the start of exposure
};

// A pose as an operator writes it: mm and degrees, R = Rz(rz) * Ry(ry) * Rx(rx).
struct PoseSetting {
  double x_mm = 0, y_mm = 0, z_mm = 0;
  double rx_deg = 0, ry_deg = 0, rz_deg = 0;
};

// The simulated cell's calibration plate (simulation.calibration_plate): the ground truth the
// calibration workflow must recover. The plate itself is the calibration.board.
struct SimPlateSettings {
  bool enabled = false;                     // the key is present: the simulated cell can show the plate
  double room_light_dn = 150;               // ambient grey level while the plate is shown (an evenly lit room)
  PoseSetting eye_to_hand_base_T_camera;    // eye-to-hand: camera fixed above the cell ...
  PoseSetting eye_to_hand_flange_T_plate;   // ... plate held by the flange
  PoseSetting eye_in_hand_flange_T_camera;  // eye-in-hand: camera on the flange ...
  PoseSetting eye_in_hand_base_T_plate;     // ... plate lying in the cell
};

struct SimulationSettings {
  int parts_per_bin = 6;
  std::uint64_t seed = 1;
  double floor_distance_mm = 330;  // camera to bin floor along the optical axis
  bool noise = true;
  SimPlateSettings plate;
  // Eye-in-hand (simulation.eye_in_hand_view): the flange pose, robot base frame, from which the
  // camera on the flange sees the bin as laid out; the bin then stays put in the base frame and
  // every capture sees it from the flange pose of its job (a second look moves the camera). Unset:
  // every capture sees the bin as laid out, wherever the PLC says the robot is.
  std::optional<Eigen::Isometry3d> eye_in_hand_view;
  // The simulated gripper (simulation.gripper), for gripper_check: the part the robot took is held
  // where the vision's pose put it relative to the true one, then displaced by `slip` (model frame
  // of the part: where it sits in the gripper relative to where it should); every drop_every-th
  // part taken falls out before the check (0: none does).
  Eigen::Isometry3d gripper_slip = Eigen::Isometry3d::Identity();
  int gripper_drop_every = 0;
};

// second_look: when an eye-in-hand cell takes a second frame set from another camera pose and
// fuses it with the first (docs/pose.md "Second look", docs/register-map.md).
enum class SecondLookWhen : std::uint8_t {
  Off,     // one look per job
  Unsure,  // when the first look would withhold its pick (ambiguous or below pick.min_score)
  Always,  // after every first look that found a part
};
struct SecondLookSettings {
  SecondLookWhen when = SecondLookWhen::Off;
  double tilt_deg = 25;  // out-of-plane turn of the second camera about the part's centre, 5..60
};

// gripper_check (paper Sec. 4.6): a standard camera on the arm, fixed to the tool and focused on
// the gripper tip, checks a grasped part (COMMAND CHECK_GRIP, docs/register-map.md "Gripper
// check"). Its image is taken as it comes (no lens distortion removed) and compared with the part
// rendered at its ideal pose in the gripper: camera_T_part = tool_T_camera^-1 * part_T_grasp^-1.
enum class GripperCameraType : std::uint8_t { Simulated, V4L2 };
struct GripperCheckSettings {
  bool enabled = false;  // the section is present
  GripperCameraType type = GripperCameraType::Simulated;
  std::string device = "/dev/video1";  // V4L2 node
  int width = 640, height = 480;       // px
  double fx = 900, fy = 900;           // px, focal lengths
  double cx = 319.5, cy = 239.5;       // px, principal point
  int dequeue_timeout_ms = 1000;
  Eigen::Isometry3d tool_T_camera = Eigen::Isometry3d::Identity();  // the camera in the tool (grasp) frame, mm
  double max_translation_mm = 1.5;                                  // measured vs ideal pose beyond this: a pose error
  double max_rotation_deg = 2.0;                                    // likewise, degrees
  double max_cost_px = 2.0;          // mean edge distance of the fitted model above this: not grasped
  double min_inlier_fraction = 0.6;  // model edge points matched below this share: not grasped
};

// mfcd-ctl calibrate: the checkerboard the operator shows and the lens model to fit. The
// result is written to camera.model (the file the cell loads), keeping <file>.previous.
struct CalibrationSettings {
  int board_columns = 9;  // inner corners per row
  int board_rows = 6;     // inner corners per column
  double square_mm = 10;
  std::string distortion = "radial";  // none | radial | radial-tangential | full
};

struct VisionSettings {
  // Every key of the section but floor_check and search_distances_mm is a parameter of the
  // pipeline's table (vision/pipeline/pipeline_parameters.hpp), read into this config; the
  // template files, grasp features and floor distance are added from the recipes and pick.
  vision::PipelineConfig pipeline;
  // The bin floor (pick.bin_floor_distance_mm) as a constraint (PipelineConfig::floor). Off by
  // default: a floor distance left at its default would refuse every part of a deeper cell.
  bool floor_check = false;
};

struct PickSettings {
  motion::PickChoiceConfig choice;
  double bin_floor_distance_mm = 330;  // for the height-above-floor term of the pick choice
};

struct SnapshotSettings {
  fs::path directory = "/var/lib/mfcd/snapshots";
  std::uint64_t quota_bytes = 200ull << 20;
  bool on_failure = true;  // save failed and empty cycles automatically
  // Save a job's frame set when the PLC reports its pick failed (PICK_RESULT other than ok),
  // if no later cycle has replaced it.
  bool on_failed_pick = true;
};

struct DaemonConfig {
  std::string source;                 // file path, or "<embedded sim.yaml>"
  std::vector<fs::path> search_path;  // where relative paths were looked up

  RunMode mode = RunMode::Triggered;
  int cycle_budget_ms = 1000;
  int default_recipe = 0;
  fs::path control_socket = "/run/mfcd/control.sock";
  int realtime_priority = 50;  // SCHED_FIFO priority of the acquisition thread; 0 = don't ask
  bool lock_memory = true;
  LogLevel log_level = LogLevel::Info;

  CameraSettings camera;
  LightsSettings lights;
  int settle_us = 0;
  int max_stale_frames = 4;
  SimulationSettings simulation;
  VisionSettings vision;
  std::vector<RecipeConfig> recipes;
  PickSettings pick;
  motion::HandEyeCalibration hand_eye;
  motion::ModbusServerConfig modbus;
  bool can_enabled = false;
  motion::CanConfig can;
  SecondLookSettings second_look;
  GripperCheckSettings gripper_check;
  SnapshotSettings snapshots;
  WebSettings web;
  fs::path web_root;  // the page's folder (index.html, app.js, style.css)
  CalibrationSettings calibration;

  const RecipeConfig* recipe(int id) const;
};

// The embedded default (config/sim.yaml compiled into the binary).
const char* embedded_sim_config();

// Directories searched for relative paths, in order: `config_dir` (if not empty), `data_dir` (if
// not empty), the compiled-in development directories (build tree, source config/), /var/lib/mfcd.
std::vector<fs::path> search_path(const fs::path& config_dir, const fs::path& data_dir);

// Parses and validates; throws ConfigError.
DaemonConfig parse_config(const std::string& yaml_text, const std::string& source,
                          const std::vector<fs::path>& search_path);
// Reads `file` and parses it with search_path(file's directory, data_dir).
DaemonConfig load_config_file(const fs::path& file, const fs::path& data_dir);
DaemonConfig load_embedded_config(const fs::path& data_dir);

}  // namespace mfcd::daemon
