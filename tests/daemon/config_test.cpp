// Configuration parsing and validation: every error names the key and the line.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <fstream>
#include <sstream>

#include "daemon/config.hpp"
#include "daemon/frame_source.hpp"
#include "vision/camera/camera.hpp"
#include "vision/pipeline/pipeline_parameters.hpp"

#include <unistd.h>

using namespace mfcd::daemon;

namespace {

const std::vector<fs::path> kPath{MFC_SOURCE_DIR "/config", MFC_BINARY_DIR};

// A minimal valid file; tests splice errors into it at known lines.
std::string minimal(const std::string& extra = "",
                    const std::string& recipes = "recipes:\n  - {id: 0, part: any, obj_id: 0}\n") {
  return "camera:\n  model: camera-sim.yaml\n" + recipes + extra;
}

// Parses `text` and returns the error (fails the test if it parses).
ConfigError error_of(const std::string& text) {
  try {
    parse_config(text, "test.yaml", kPath);
  } catch (const ConfigError& e) {
    return e;
  }
  ADD_FAILURE() << "parsed without error:\n" << text;
  return ConfigError("", 0, "", "");
}

}  // namespace

TEST(Config, MinimalFileGetsTheDocumentedDefaults) {
  const DaemonConfig c = parse_config(minimal(), "test.yaml", kPath);
  EXPECT_EQ(c.mode, RunMode::Triggered);
  EXPECT_EQ(c.cycle_budget_ms, 1000);
  EXPECT_EQ(c.modbus.port, 502);
  EXPECT_EQ(c.modbus.idle_timeout, std::chrono::milliseconds(60000));
  EXPECT_EQ(c.control_socket, "/run/mfcd/control.sock");
  EXPECT_EQ(c.camera.model, fs::path(MFC_SOURCE_DIR "/config/camera-sim.yaml"));
  EXPECT_FALSE(c.can_enabled);
  ASSERT_EQ(c.recipes.size(), 1u);
}

TEST(Config, UnknownKeyIsNamedWithItsLine) {
  const ConfigError e = error_of(minimal("daemon:\n  mode: triggered\n  cycle_budget: 100\n"));
  EXPECT_EQ(e.key(), "daemon.cycle_budget");
  EXPECT_EQ(e.line(), 7);
  EXPECT_NE(std::string(e.what()).find("test.yaml:7: daemon.cycle_budget: unknown key"), std::string::npos) << e.what();
}

TEST(Config, WrongTypeAndRangeNameKeyAndLine) {
  ConfigError e = error_of(minimal("daemon:\n  cycle_budget_ms: fast\n"));
  EXPECT_EQ(e.key(), "daemon.cycle_budget_ms");
  EXPECT_EQ(e.line(), 6);
  EXPECT_NE(std::string(e.what()).find("'fast' is not an integer"), std::string::npos) << e.what();

  e = error_of(minimal("modbus:\n  bind_address: 127.0.0.1\n  port: 70000\n"));
  EXPECT_EQ(e.key(), "modbus.port");
  EXPECT_EQ(e.line(), 7);
  EXPECT_NE(std::string(e.what()).find("out of range 0..65535"), std::string::npos) << e.what();

  // A file name longer than NAME_MAX (found by the daemon_config fuzz harness): named, not thrown.
  e = error_of("camera:\n  model: " + std::string(300, 'a') + "\nrecipes:\n  - {id: 0, part: any, obj_id: 0}\n");
  EXPECT_EQ(e.key(), "camera.model");
  EXPECT_NE(std::string(e.what()).find("not found in the search path"), std::string::npos) << e.what();

  e = error_of(minimal("modbus:\n  idle_timeout_ms: 50\n"));
  EXPECT_EQ(e.key(), "modbus.idle_timeout_ms");
  EXPECT_EQ(e.line(), 6);
  EXPECT_NE(std::string(e.what()).find("out of range 100..3600000"), std::string::npos) << e.what();

  e = error_of(minimal("daemon:\n  mode: sometimes\n"));
  EXPECT_EQ(e.key(), "daemon.mode");
  EXPECT_NE(std::string(e.what()).find("not one of triggered, continuous"), std::string::npos) << e.what();

  e = error_of(minimal("daemon:\n  lock_memory: maybe\n"));
  EXPECT_EQ(e.key(), "daemon.lock_memory");

  e = error_of(minimal("vision:\n  refine_candidates: 65\n"));
  EXPECT_EQ(e.key(), "vision.refine_candidates");
  EXPECT_EQ(e.line(), 6);
  EXPECT_NE(std::string(e.what()).find("out of range 0..64"), std::string::npos) << e.what();
}

TEST(Config, RefinementIsOffUnlessAsked) {
  EXPECT_EQ(parse_config(minimal(), "test.yaml", kPath).vision.pipeline.refine_candidates, 0);
  EXPECT_EQ(
      parse_config(minimal("vision:\n  refine_candidates: 2\n"), "test.yaml", kPath).vision.pipeline.refine_candidates,
      2);
}

// The floor check needs a floor distance someone set: off unless asked; the tolerance is ranged.
TEST(Config, FloorCheckIsOffUnlessAsked) {
  const DaemonConfig plain = parse_config(minimal(), "test.yaml", kPath);
  EXPECT_FALSE(plain.vision.floor_check);
  EXPECT_EQ(plain.vision.pipeline.floor.tolerance_mm, 3.0);
  const DaemonConfig on =
      parse_config(minimal("vision:\n  floor_check: true\n  floor_tolerance_mm: 2.5\n"), "test.yaml", kPath);
  EXPECT_TRUE(on.vision.floor_check);
  EXPECT_EQ(on.vision.pipeline.floor.tolerance_mm, 2.5);
  const ConfigError e = error_of(minimal("vision:\n  floor_tolerance_mm: -1\n"));
  EXPECT_EQ(e.key(), "vision.floor_tolerance_mm");
  EXPECT_EQ(e.line(), 6);
}

// Search rounds: one unless asked, 1..4, a bad value named with its key and line.
TEST(Config, SearchRoundsAreOneUnlessAsked) {
  EXPECT_EQ(parse_config(minimal(), "test.yaml", kPath).vision.pipeline.search_rounds, 1);
  EXPECT_EQ(parse_config(minimal("vision:\n  search_rounds: 2\n"), "test.yaml", kPath).vision.pipeline.search_rounds,
            2);
  for (const char* bad : {"0", "5", "two"}) {
    const ConfigError e = error_of(minimal(std::string("vision:\n  search_rounds: ") + bad + "\n"));
    EXPECT_EQ(e.key(), "vision.search_rounds") << bad;
    EXPECT_EQ(e.line(), 6) << bad;
  }
}

// Escalation: the pipeline's default unless set, 0..2, a bad value named with its key and line.
TEST(Config, EscalationThresholdIsThePipelinesUnlessSet) {
  EXPECT_EQ(parse_config(minimal(), "test.yaml", kPath).vision.pipeline.escalate_below,
            mfcd::vision::PipelineConfig{}.escalate_below);
  EXPECT_EQ(parse_config(minimal("vision:\n  escalate_below: 0\n"), "test.yaml", kPath).vision.pipeline.escalate_below,
            0.0);
  EXPECT_EQ(
      parse_config(minimal("vision:\n  escalate_below: 0.15\n"), "test.yaml", kPath).vision.pipeline.escalate_below,
      0.15);
  for (const char* bad : {"-0.1", "2.5", "high"}) {
    const ConfigError e = error_of(minimal(std::string("vision:\n  escalate_below: ") + bad + "\n"));
    EXPECT_EQ(e.key(), "vision.escalate_below") << bad;
    EXPECT_EQ(e.line(), 6) << bad;
  }
}

// Every cell parameter of the pipeline's table is a key of the vision section, read into the
// pipeline's config; one out of its range is named with its key and line; a pair that must agree
// is refused naming the section.
static std::string number_text(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

TEST(Config, VisionSectionIsThePipelinesParameterTable) {
  using mfcd::vision::PipelineParameter;
  int cell = 0;
  for (const PipelineParameter& p : mfcd::vision::pipeline_parameters()) {
    const std::string key = p.key;
    if (!p.cell) {
      EXPECT_EQ(error_of(minimal("vision:\n  " + key + ": 1\n")).key(), "vision." + key);
      continue;
    }
    ++cell;
    // A value in range other than the default: the maximum, or the minimum when that is the default.
    double v = std::isinf(p.max) ? p.min + 1 : p.max;
    if (v == p.default_value()) v = p.min;
    const std::string text = p.type == PipelineParameter::Type::boolean ? (v != 0 ? "true" : "false") : number_text(v);
    const std::string extra = key == "fit_inlier_cost_px"     ? "  fit_score_gate_px: 100\n"
                              : key == "edges_low_threshold"  ? "  edges_high_threshold: 8\n"
                              : key == "edges_high_threshold" ? "  edges_low_threshold: 0\n"
                              : key == "fit_score_gate_px"    ? "  fit_inlier_cost_px: 0.01\n"
                                                              : "";
    const DaemonConfig c = parse_config(minimal("vision:\n  " + key + ": " + text + "\n" + extra), "test.yaml", kPath);
    EXPECT_EQ(p.get(c.vision.pipeline), v) << key;
    if (p.type != PipelineParameter::Type::boolean) {
      const ConfigError e = error_of(minimal("vision:\n  " + key + ": " + number_text(p.min - 1) + "\n"));
      EXPECT_EQ(e.key(), "vision." + key);
      EXPECT_EQ(e.line(), 6) << key;
    }
  }
  EXPECT_GT(cell, 30);
  const ConfigError e = error_of(minimal("vision:\n  fit_score_gate_px: 1\n  fit_inlier_cost_px: 2\n"));
  EXPECT_EQ(e.key(), "vision");
  EXPECT_NE(std::string(e.what()).find("fit_inlier_cost_px"), std::string::npos) << e.what();
}

// Search distances: a list of 1..4 numbers; an element out of range is named with its line.
TEST(Config, SearchDistancesAreAListOfDistances) {
  EXPECT_TRUE(parse_config(minimal(), "test.yaml", kPath).vision.pipeline.distances_mm.empty());
  const DaemonConfig two = parse_config(minimal("vision:\n  search_distances_mm: [315, 299]\n"), "test.yaml", kPath);
  EXPECT_EQ(two.vision.pipeline.distances_mm, (std::vector<double>{315, 299}));
  ConfigError e = error_of(minimal("vision:\n  search_distances_mm:\n    - 300\n    - 10\n"));
  EXPECT_EQ(e.key(), "vision.search_distances_mm");
  EXPECT_EQ(e.line(), 8);  // the element's own line
  EXPECT_NE(std::string(e.what()).find("out of range"), std::string::npos) << e.what();
  e = error_of(minimal("vision:\n  search_distances_mm: 300\n"));
  EXPECT_EQ(e.key(), "vision.search_distances_mm");
  EXPECT_NE(std::string(e.what()).find("list of 1 to 4"), std::string::npos) << e.what();
}

// Grasp features: a list per recipe (for one part type), each a spot in the part's model frame
// with its free radius, approach direction and tilt limit; errors name the feature's key and line.
TEST(Config, GraspFeaturesAreReadPerRecipe) {
  const std::string recipes =
      "recipes:\n"
      "  - id: 4\n"
      "    part: tnut\n"
      "    obj_id: 4\n"
      "    grasp_features:\n"
      "      - {x_mm: 0, y_mm: 0, z_mm: 18, radius_mm: 6, approach: {z: 1}, max_tilt_deg: 45}\n"
      "      - {z_mm: 2}\n"
      "  - {id: 0, part: any, obj_id: 0}\n";
  const DaemonConfig c = parse_config(minimal("", recipes), "test.yaml", kPath);
  ASSERT_EQ(c.recipes.size(), 2u);
  ASSERT_EQ(c.recipes[0].grasp_features.size(), 2u);
  const GraspFeatureSetting& a = c.recipes[0].grasp_features[0];
  EXPECT_EQ(a.z_mm, 18);
  EXPECT_EQ(a.radius_mm, 6);
  EXPECT_EQ(a.approach, (std::array<double, 3>{0, 0, 1}));
  EXPECT_EQ(a.max_tilt_deg, 45);
  const GraspFeatureSetting& b = c.recipes[0].grasp_features[1];  // the documented defaults
  EXPECT_EQ(b.radius_mm, 4);
  EXPECT_EQ(b.approach, (std::array<double, 3>{0, 0, 0}));
  EXPECT_EQ(b.max_tilt_deg, 60);
  EXPECT_TRUE(c.recipes[1].grasp_features.empty());

  const std::string head = "recipes:\n  - id: 4\n    part: tnut\n    obj_id: 4\n    grasp_features:\n";
  ConfigError e = error_of(minimal("", head + "      - {z_mm: 18, radius_mm: 0}\n"));
  EXPECT_EQ(e.key(), "recipes[0].grasp_features[0].radius_mm");
  EXPECT_EQ(e.line(), 8);
  e = error_of(minimal("", head + "      - {z_mm: 18}\n      - {z_mm: 0, approach: {x: 0, y: 0, z: 0}}\n"));
  EXPECT_EQ(e.key(), "recipes[0].grasp_features[1].approach");
  EXPECT_EQ(e.line(), 9);
  EXPECT_NE(std::string(e.what()).find("must not be zero"), std::string::npos) << e.what();
  e = error_of(minimal("", head + "      - {z_mm: 18, diameter_mm: 8}\n"));
  EXPECT_EQ(e.key(), "recipes[0].grasp_features[0].diameter_mm");
  e = error_of(minimal("", head + "      z_mm: 18\n"));
  EXPECT_EQ(e.key(), "recipes[0].grasp_features");
  EXPECT_NE(std::string(e.what()).find("list of 1 to 8"), std::string::npos) << e.what();
  e = error_of(
      minimal("", "recipes:\n  - id: 0\n    part: any\n    obj_id: 0\n    grasp_features:\n      - {z_mm: 1}\n"));
  EXPECT_EQ(e.key(), "recipes[0].grasp_features");
  EXPECT_EQ(e.line(), 8);  // where the list starts
  EXPECT_NE(std::string(e.what()).find("obj_id 0"), std::string::npos) << e.what();
}

TEST(Config, MissingRequiredKeys) {
  ConfigError e = error_of("recipes:\n  - {id: 0, part: any, obj_id: 0}\n");
  EXPECT_EQ(e.key(), "camera.model");
  e = error_of("camera:\n  model: camera-sim.yaml\n");
  EXPECT_EQ(e.key(), "recipes");
  e = error_of(minimal("", "recipes:\n  - {id: 0, obj_id: 0}\n"));
  EXPECT_EQ(e.key(), "recipes[0].part");
  EXPECT_EQ(e.line(), 4);
}

TEST(Config, MissingFileNamesTheSearchPath) {
  const ConfigError e =
      error_of(minimal("", "recipes:\n  - id: 3\n    part: wheel\n    obj_id: 6\n    mesh: parts/nope.stl\n"));
  EXPECT_EQ(e.key(), "recipes[0].mesh");
  EXPECT_EQ(e.line(), 7);
  const std::string what = e.what();
  EXPECT_NE(what.find("'parts/nope.stl' not found in the search path"), std::string::npos) << what;
  EXPECT_NE(what.find(MFC_BINARY_DIR), std::string::npos) << what;
}

TEST(Config, DuplicateRecipeAndMissingDefaultRecipe) {
  ConfigError e = error_of(minimal("", "recipes:\n  - {id: 1, part: a, obj_id: 0}\n  - {id: 1, part: b, obj_id: 0}\n"));
  EXPECT_EQ(e.key(), "recipes[1].id");
  EXPECT_EQ(e.line(), 5);
  e = error_of(minimal("daemon:\n  default_recipe: 9\n"));
  EXPECT_EQ(e.key(), "daemon.default_recipe");
}

TEST(Config, LedOffsetsMustBeEightDistinctLines) {
  ConfigError e = error_of(minimal("lights:\n  type: gpiod\n  offsets: [0, 1, 2]\n"));
  EXPECT_EQ(e.key(), "lights.offsets");
  EXPECT_EQ(e.line(), 7);
  e = error_of(minimal("lights:\n  offsets: [0, 1, 2, 3, 4, 5, 6, 3]\n"));
  EXPECT_NE(std::string(e.what()).find("used twice"), std::string::npos) << e.what();
}

TEST(Config, YamlSyntaxErrorHasItsLine) {
  const ConfigError e = error_of("camera:\n  model: [unclosed\nrecipes: []\n");
  EXPECT_GT(e.line(), 0);
  EXPECT_NE(std::string(e.what()).find("YAML syntax error"), std::string::npos) << e.what();
}

TEST(Config, HandEyeIsValidatedAndEachSetupTakesItsOwnCameraKey) {
  const DaemonConfig c = parse_config(minimal("hand_eye:\n  setup: eye_in_hand\n  flange_T_camera: {z_mm: 150}\n"), "t",
                                      {MFC_SOURCE_DIR "/config"});
  EXPECT_EQ(c.hand_eye.setup, mfcd::motion::HandEyeSetup::EyeInHand);
  EXPECT_DOUBLE_EQ(c.hand_eye.camera.translation().z(), 150);
  ConfigError e = error_of(minimal("hand_eye:\n  setup: eye_in_hand\n  base_T_camera: {z_mm: 150}\n"));
  EXPECT_EQ(e.key(), "hand_eye.base_T_camera");
  EXPECT_EQ(e.line(), 7);
  e = error_of(minimal("hand_eye:\n  flange_T_camera: {z_mm: 150}\n"));
  EXPECT_EQ(e.key(), "hand_eye.flange_T_camera");
  e = error_of(minimal("hand_eye:\n  base_T_camera: {x_mm: 1, yy_mm: 2}\n"));
  EXPECT_EQ(e.key(), "hand_eye.base_T_camera.yy_mm");
}

TEST(Config, SecondLookMovesTheCameraSoItNeedsTheCameraOnTheFlange) {
  const std::string in_hand = "hand_eye:\n  setup: eye_in_hand\n  flange_T_camera: {z_mm: 150}\n";
  DaemonConfig c = parse_config(minimal(in_hand + "second_look:\n  when: unsure\n  tilt_deg: 30\n"), "t", kPath);
  EXPECT_EQ(c.second_look.when, SecondLookWhen::Unsure);
  EXPECT_DOUBLE_EQ(c.second_look.tilt_deg, 30);
  EXPECT_EQ(parse_config(minimal(), "t", kPath).second_look.when, SecondLookWhen::Off);
  // Lines: camera 1-2, recipes 3-4, then the extra text.
  ConfigError e = error_of(minimal("second_look:\n  when: always\n"));
  EXPECT_EQ(e.key(), "second_look.when");
  EXPECT_EQ(e.line(), 6);
  EXPECT_NE(std::string(e.what()).find("eye_in_hand"), std::string::npos) << e.what();
  e = error_of(minimal(in_hand + "second_look:\n  when: twice\n"));
  EXPECT_EQ(e.key(), "second_look.when");
  e = error_of(minimal(in_hand + "second_look:\n  tilt_deg: 75\n"));
  EXPECT_EQ(e.key(), "second_look.tilt_deg");
  // The simulated camera follows the robot only with the camera on the flange.
  const std::string view = "simulation:\n  eye_in_hand_view: {x_mm: 400, z_mm: 600, rx_deg: 180}\n";
  c = parse_config(minimal(view + in_hand), "t", kPath);
  ASSERT_TRUE(c.simulation.eye_in_hand_view.has_value());
  EXPECT_DOUBLE_EQ(c.simulation.eye_in_hand_view->translation().x(), 400);
  e = error_of(minimal(view));
  EXPECT_EQ(e.key(), "simulation.eye_in_hand_view");
  EXPECT_EQ(e.line(), 6);
}

TEST(Config, GripperCheckNeedsTheCameraOnTheToolAndNamesItsKeys) {
  const std::string grip =
      "gripper_check:\n  camera: {width: 800, height: 600, fx: 1000, fy: 1010}\n"
      "  tool_T_camera: {z_mm: 200, rx_deg: 180}\n  max_rotation_deg: 3\n";
  DaemonConfig c = parse_config(minimal(grip), "t", kPath);
  EXPECT_TRUE(c.gripper_check.enabled);
  EXPECT_EQ(c.gripper_check.type, GripperCameraType::Simulated);
  EXPECT_EQ(c.gripper_check.width, 800);
  EXPECT_DOUBLE_EQ(c.gripper_check.cx, 399.5);  // the image centre unless given
  EXPECT_DOUBLE_EQ(c.gripper_check.fy, 1010);
  EXPECT_DOUBLE_EQ(c.gripper_check.tool_T_camera.translation().z(), 200);
  EXPECT_DOUBLE_EQ(c.gripper_check.max_rotation_deg, 3);
  EXPECT_DOUBLE_EQ(c.gripper_check.max_translation_mm, 1.5);
  EXPECT_FALSE(parse_config(minimal(), "t", kPath).gripper_check.enabled);
  // Lines: camera 1-2, recipes 3-4, then the extra text.
  ConfigError e = error_of(minimal("gripper_check:\n  camera: {width: 640}\n"));
  EXPECT_EQ(e.key(), "gripper_check.tool_T_camera");
  e = error_of(minimal("gripper_check:\n  camera: {type: usb}\n  tool_T_camera: {z_mm: 1}\n"));
  EXPECT_EQ(e.key(), "gripper_check.camera.type");
  EXPECT_EQ(e.line(), 6);
  e = error_of(minimal("gripper_check:\n  camera: {cx: 900}\n  tool_T_camera: {z_mm: 1}\n"));
  EXPECT_EQ(e.key(), "gripper_check.camera.cx");
  e = error_of(minimal("gripper_check:\n  tool_T_camera: {z_mm: 1, tilt: 3}\n"));
  EXPECT_EQ(e.key(), "gripper_check.tool_T_camera.tilt");
  e = error_of(minimal("gripper_check:\n  tool_T_camera: {z_mm: 1}\n  min_inlier_fraction: 2\n"));
  EXPECT_EQ(e.key(), "gripper_check.min_inlier_fraction");
  // The simulated gripper: its slip and how often a part falls out.
  c = parse_config(minimal("simulation:\n  gripper: {slip: {x_mm: 3, rz_deg: 5}, drop_every: 4}\n"), "t", kPath);
  EXPECT_DOUBLE_EQ(c.simulation.gripper_slip.translation().x(), 3);
  EXPECT_EQ(c.simulation.gripper_drop_every, 4);
  e = error_of(minimal("simulation:\n  gripper: {drop_every: -1}\n"));
  EXPECT_EQ(e.key(), "simulation.gripper.drop_every");
}

TEST(Config, RelativePathsResolveInSearchPathOrder) {
  const fs::path dir = fs::temp_directory_path() / ("mfcd-config-test-" + std::to_string(::getpid()));
  fs::create_directories(dir / "first");
  fs::create_directories(dir / "second");
  fs::copy_file(MFC_SOURCE_DIR "/config/camera-sim.yaml", dir / "second" / "cam.yaml",
                fs::copy_options::overwrite_existing);
  const std::string text = "camera:\n  model: cam.yaml\nrecipes:\n  - {id: 0, part: any, obj_id: 0}\n";
  DaemonConfig c = parse_config(text, "t", {dir / "first", dir / "second"});
  EXPECT_EQ(c.camera.model, dir / "second" / "cam.yaml");
  fs::copy_file(MFC_SOURCE_DIR "/config/camera-sim.yaml", dir / "first" / "cam.yaml",
                fs::copy_options::overwrite_existing);
  c = parse_config(text, "t", {dir / "first", dir / "second"});
  EXPECT_EQ(c.camera.model, dir / "first" / "cam.yaml") << "the config file's directory comes first";

  // load_config_file puts the file's own directory first.
  std::ofstream(dir / "first" / "mfcd.yaml") << text;
  c = load_config_file(dir / "first" / "mfcd.yaml", dir / "second");
  EXPECT_EQ(c.camera.model, dir / "first" / "cam.yaml");
  EXPECT_EQ(c.search_path.at(0), dir / "first");
  EXPECT_EQ(c.search_path.at(1), dir / "second");
  ASSERT_GE(c.search_path.size(), 4u);
  EXPECT_EQ(c.search_path[c.search_path.size() - 2], "/var/lib/mfcd");
  EXPECT_EQ(c.search_path.back(), "/usr/share/mfcd") << "what the package ships, last";
  fs::remove_all(dir);
}

TEST(Config, EmbeddedSimConfigIsTheShippedFile) {
  std::ifstream in(MFC_SOURCE_DIR "/config/sim.yaml");
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(text.str(), embedded_sim_config());
}

TEST(Config, SimAndCellConfigsParse) {
  if (!fs::exists(MFC_BINARY_DIR "/templates"))
    GTEST_SKIP() << "no " MFC_BINARY_DIR "/templates yet (the template files are generated by the vision build)";
  const DaemonConfig sim = load_embedded_config({});
  EXPECT_EQ(sim.modbus.port, 1502);
  EXPECT_EQ(sim.modbus.bind_address, "127.0.0.1");
  EXPECT_EQ(sim.recipes.size(), 7u);
  EXPECT_TRUE(sim.vision.floor_check);  // the simulated bin's floor is at pick.bin_floor_distance_mm
  EXPECT_EQ(sim.vision.pipeline.search_rounds, 2);
  EXPECT_EQ(sim.pick.bin_floor_distance_mm, sim.simulation.floor_distance_mm);
  for (const auto& r : sim.recipes)
    if (r.obj_id != 0) {
      EXPECT_TRUE(r.templates && r.mesh) << r.part;
    }
  // The simulated cell's grasp features are the evaluation's (config/parts/grasp-features.csv,
  // mfc-eval --grasp-features): the pick figures of docs/results.md are the cell's.
  std::ifstream table(MFC_SOURCE_DIR "/config/parts/grasp-features.csv");
  ASSERT_TRUE(table) << "config/parts/grasp-features.csv";
  std::vector<std::pair<int, std::array<double, 8>>> listed;
  for (std::string line; std::getline(table, line);) {
    if (line.empty() || line[0] == '#' || line.rfind("name,", 0) == 0) continue;
    std::stringstream fields(line);
    std::string name, field;
    std::getline(fields, name, ',');
    std::getline(fields, field, ',');
    std::pair<int, std::array<double, 8>> f{std::stoi(field), {}};
    for (double& v : f.second) {
      std::getline(fields, field, ',');
      v = std::stod(field);
    }
    listed.push_back(f);
  }
  std::vector<std::pair<int, std::array<double, 8>>> configured;
  for (const auto& r : sim.recipes)
    for (const auto& g : r.grasp_features)
      configured.push_back(
          {r.obj_id,
           {g.x_mm, g.y_mm, g.z_mm, g.radius_mm, g.approach[0], g.approach[1], g.approach[2], g.max_tilt_deg}});
  EXPECT_EQ(configured, listed);
  EXPECT_EQ(configured.size(), 12u);
  EXPECT_GT(sim.pick.choice.weight_grasp, 0);

  const DaemonConfig cell = load_config_file(MFC_SOURCE_DIR "/config/cell.yaml", MFC_BINARY_DIR);
  EXPECT_EQ(cell.camera.type, CameraType::V4L2);
  EXPECT_EQ(cell.lights.type, LightsType::Gpiod);
  EXPECT_TRUE(cell.can_enabled);
}

TEST(Config, CalibrationBoardAndSimulatedPlate) {
  DaemonConfig c = parse_config(minimal(), "test.yaml", kPath);
  EXPECT_EQ(c.calibration.board_columns, 9);
  EXPECT_EQ(c.calibration.board_rows, 6);
  EXPECT_EQ(c.calibration.square_mm, 10);
  EXPECT_EQ(c.calibration.distortion, "radial");
  EXPECT_FALSE(c.simulation.plate.enabled);

  c = parse_config(minimal("calibration:\n  board: 7x5\n  square_mm: 25\n  distortion: none\n"
                           "simulation:\n  calibration_plate:\n    room_light_dn: 120\n"
                           "    eye_to_hand:\n      base_T_camera: {x_mm: 600, z_mm: 900, rx_deg: 180}\n"
                           "      flange_T_plate: {z_mm: 20}\n"
                           "    eye_in_hand:\n      flange_T_camera: {x_mm: 40, z_mm: 90}\n"
                           "      base_T_plate: {x_mm: 450, rx_deg: 180}\n"),
                   "test.yaml", kPath);
  EXPECT_EQ(c.calibration.board_columns, 7);
  EXPECT_EQ(c.calibration.board_rows, 5);
  EXPECT_EQ(c.calibration.square_mm, 25);
  EXPECT_EQ(c.calibration.distortion, "none");
  EXPECT_TRUE(c.simulation.plate.enabled);
  EXPECT_EQ(c.simulation.plate.room_light_dn, 120);
  EXPECT_EQ(c.simulation.plate.eye_to_hand_base_T_camera.x_mm, 600);
  EXPECT_EQ(c.simulation.plate.eye_to_hand_base_T_camera.rx_deg, 180);
  EXPECT_EQ(c.simulation.plate.eye_in_hand_base_T_plate.x_mm, 450);

  ConfigError e = error_of(minimal("calibration:\n  board: 9by6\n"));
  EXPECT_EQ(e.key(), "calibration.board");
  EXPECT_EQ(e.line(), 6);
  EXPECT_NE(std::string(e.what()).find("COLUMNSxROWS"), std::string::npos) << e.what();
  e = error_of(minimal("calibration:\n  board: 6x6\n"));  // a square board has no unique orientation
  EXPECT_EQ(e.key(), "calibration.board");
  e = error_of(minimal("calibration:\n  square_mm: 0\n"));
  EXPECT_EQ(e.key(), "calibration.square_mm");
  e = error_of(minimal("calibration:\n  distortion: fisheye\n"));
  EXPECT_EQ(e.key(), "calibration.distortion");
  e = error_of(minimal("simulation:\n  calibration_plate:\n    eye_to_hand:\n      base_T_camera: {x_mm: 1}\n"));
  EXPECT_EQ(e.key(), "simulation.calibration_plate.eye_to_hand.flange_T_plate");
  EXPECT_NE(std::string(e.what()).find("missing (required)"), std::string::npos) << e.what();
  e = error_of(minimal("simulation:\n  calibration_plate:\n    eye_to_hand:\n      base_T_camera: {x_mm: 1, q: 2}\n"));
  EXPECT_EQ(e.key(), "simulation.calibration_plate.eye_to_hand.base_T_camera.q");
  EXPECT_EQ(e.line(), 8);
}

// hand_eye.from_camera_file: the camera pose an applied hand-eye calibration wrote.
TEST(Config, HandEyeFromTheCameraFile) {
  const fs::path dir = fs::temp_directory_path() / ("mfcd-config-he-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  mfcd::vision::CameraConfig cam = mfcd::vision::load_camera_config(MFC_SOURCE_DIR "/config/camera-sim.yaml");
  mfcd::vision::save_camera_config(cam, dir / "plain.yaml");
  mfcd::vision::HandEye he;
  he.mode = mfcd::vision::HandEye::Mode::eye_to_hand;
  he.camera_pose = cv::Matx44d(0, 1, 0, 620, 1, 0, 0, 110, 0, 0, -1, 950, 0, 0, 0, 1);
  cam.hand_eye = he;
  mfcd::vision::save_camera_config(cam, dir / "calibrated.yaml");
  const auto text = [&](const std::string& file, const std::string& he_extra) {
    return "camera:\n  model: " + (dir / file).string() + "\nrecipes:\n  - {id: 0, part: any, obj_id: 0}\nhand_eye:\n" +
           he_extra;
  };
  const DaemonConfig c = parse_config(text("calibrated.yaml", "  from_camera_file: true\n"), "test.yaml", kPath);
  EXPECT_NEAR(c.hand_eye.camera.translation().x(), 620, 1e-9);
  EXPECT_NEAR(c.hand_eye.camera.translation().z(), 950, 1e-9);
  EXPECT_NEAR(c.hand_eye.camera.linear()(2, 2), -1, 1e-12);

  ConfigError e = error_of(text("plain.yaml", "  from_camera_file: true\n"));
  EXPECT_EQ(e.key(), "hand_eye.from_camera_file");
  EXPECT_EQ(e.line(), 6);
  EXPECT_NE(std::string(e.what()).find("has no hand_eye section"), std::string::npos) << e.what();
  e = error_of(text("calibrated.yaml", "  from_camera_file: true\n  base_T_camera: {x_mm: 1}\n"));
  EXPECT_EQ(e.key(), "hand_eye.base_T_camera");
  fs::remove_all(dir);
}

// camera.type aravis (a GenICam camera through Aravis) and lights.type camera (the LEDs fired by its
// outputs): keys, defaults, the errors naming key and line, and the frame source built from them
// (no device is opened until activate()).
TEST(Config, AravisCameraAndCameraStrobe) {
  const std::string recipes = "recipes:\n  - {id: 0, part: any, obj_id: 0}\n";
  const std::string aravis = "camera:\n  model: camera-sim.yaml\n  type: aravis\n  device: Basler-21234567\n";
  DaemonConfig c =
      parse_config(aravis + "  gain: 2.5\n  packet_size: 8192\n" + recipes +
                       "lights:\n  type: camera\n  strobe_line: Line1\n  select_lines: [Line2, Line3, Line4]\n"
                       "  strobe_source: timer\n  strobe_pulse_us: 1500\n  active_low: true\n",
                   "test.yaml", kPath);
  EXPECT_EQ(c.camera.type, CameraType::Aravis);
  EXPECT_EQ(c.camera.device, "Basler-21234567");
  ASSERT_TRUE(c.camera.gain);
  EXPECT_DOUBLE_EQ(*c.camera.gain, 2.5);  // dB on SFNC cameras: not only integers
  EXPECT_EQ(c.camera.packet_size, 8192);
  EXPECT_EQ(c.lights.type, LightsType::Camera);
  EXPECT_EQ(c.lights.select_lines[2], "Line4");
  EXPECT_EQ(c.lights.strobe_source, StrobeSourceSetting::Timer);
  EXPECT_EQ(c.lights.strobe_pulse_us, 1500);
  const auto source = make_frame_source(c);
  EXPECT_NE(source->describe().find("Aravis Basler-21234567"), std::string::npos) << source->describe();
  EXPECT_NE(source->describe().find("strobe outputs of"), std::string::npos) << source->describe();
  EXPECT_NE(switch_leds_off(c).find("camera strobe"), std::string::npos);

  c = parse_config(aravis + recipes + "lights:\n  type: gpiod\n", "test.yaml", kPath);  // LEDs on GPIO still
  EXPECT_EQ(c.lights.strobe_line, "Line1");
  EXPECT_EQ(c.lights.strobe_source, StrobeSourceSetting::ExposureActive);
  EXPECT_NE(make_frame_source(c)->describe().find("GPIO chip"), std::string::npos);

  ConfigError e = error_of("camera:\n  model: camera-sim.yaml\n  type: aravis\n" + recipes);
  EXPECT_EQ(e.key(), "camera.device");
  EXPECT_NE(std::string(e.what()).find("camera id"), std::string::npos) << e.what();
  e = error_of(aravis + "  frame_rate: 60\n" + recipes);
  EXPECT_EQ(e.key(), "camera.frame_rate");
  EXPECT_EQ(e.line(), 5);
  e = error_of("camera:\n  model: camera-sim.yaml\n  type: v4l2\n  gain: 2.5\n" + recipes);
  EXPECT_EQ(e.key(), "camera.gain");
  EXPECT_EQ(e.line(), 4);
  e = error_of(aravis + "  packet_size: 100\n" + recipes);
  EXPECT_EQ(e.key(), "camera.packet_size");
  e = error_of(aravis + recipes + "lights:\n  type: camera\n  select_lines: [Line2, Line3]\n");
  EXPECT_EQ(e.key(), "lights.select_lines");
  EXPECT_EQ(e.line(), 9);
  e = error_of(aravis + recipes + "lights:\n  type: camera\n  select_lines:\n    - Line2\n    - Line1\n    - Line4\n");
  EXPECT_EQ(e.key(), "lights.select_lines");
  EXPECT_EQ(e.line(), 11);
  EXPECT_NE(std::string(e.what()).find("'Line1' is used twice"), std::string::npos) << e.what();
  e = error_of(aravis + recipes + "lights:\n  type: camera\n  strobe_source: timer\n");
  EXPECT_EQ(e.key(), "lights.strobe_pulse_us");
  EXPECT_EQ(e.line(), 9);

  // The pairings the frame source refuses, naming the key.
  c = parse_config(aravis + recipes, "test.yaml", kPath);  // lights default: simulated
  try {
    make_frame_source(c);
    ADD_FAILURE() << "an aravis camera with simulated lights was accepted";
  } catch (const std::runtime_error& err) {
    EXPECT_NE(std::string(err.what()).find("lights.type"), std::string::npos) << err.what();
  }
  c = parse_config("camera:\n  model: camera-sim.yaml\n  type: v4l2\n" + recipes + "lights:\n  type: camera\n",
                   "test.yaml", kPath);
  try {
    make_frame_source(c);
    ADD_FAILURE() << "camera strobe without an aravis camera was accepted";
  } catch (const std::runtime_error& err) {
    EXPECT_NE(std::string(err.what()).find("camera.type: aravis"), std::string::npos) << err.what();
  }
}
