#include "daemon/config.hpp"

#include "daemon/config_reader.hpp"

#include "vision/camera/camera.hpp"
#include "vision/pipeline/bin_picking_pipeline.hpp"
#include "vision/pipeline/pipeline_parameters.hpp"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

namespace mfcd::daemon {

using namespace config_reader;

namespace {

// "source:line: key: reason", the line and key left out when unknown. Built by appending: GCC 12
// warns -Wrestrict (falsely) on the inlined `"literal" + std::string` form here.
std::string config_error_text(const std::string& source, int line, const std::string& key, const std::string& reason) {
  std::string text = source;
  if (line > 0) text.append(":").append(std::to_string(line));
  text.append(": ");
  if (!key.empty()) text.append(key).append(": ");
  return text.append(reason);
}

}  // namespace

ConfigError::ConfigError(std::string source, int line, std::string key, const std::string& reason)
    : std::runtime_error(config_error_text(source, line, key, reason)),
      source_(std::move(source)),
      key_(std::move(key)),
      line_(line) {}

const char* to_string(RunMode m) { return m == RunMode::Triggered ? "triggered" : "continuous"; }

const RecipeConfig* DaemonConfig::recipe(int id) const {
  for (const auto& r : recipes)
    if (r.id == id) return &r;
  return nullptr;
}

#ifdef MFCD_DEV_DATA_DIRS
namespace {
// True when this program runs from the build tree that compiled it. The package installs these
// very binaries: an installed copy (a .../usr/bin/ program, also one installed under the build
// tree by the package tests) must not look for a developer's files.
bool run_from_build_tree() {
  std::error_code ec;
  const std::string exe = fs::read_symlink("/proc/self/exe", ec).string();
  const std::string build = std::string(MFCD_BUILD_DIR) + "/";
  return !ec && exe.rfind(build, 0) == 0 && exe.find("/usr/bin/", build.size() - 1) == std::string::npos;
}
}  // namespace
#endif

std::vector<fs::path> search_path(const fs::path& config_dir, const fs::path& data_dir) {
  std::vector<fs::path> path;
  if (!config_dir.empty()) path.push_back(config_dir);
  if (!data_dir.empty()) path.push_back(data_dir);
#ifdef MFCD_DEV_DATA_DIRS
  // Development runs from the build tree find the generated parts/templates, config/ and web/.
  if (run_from_build_tree()) {
    std::stringstream dev(MFCD_DEV_DATA_DIRS);
    for (std::string dir; std::getline(dev, dir, ':');)
      if (!dir.empty()) path.emplace_back(dir);
  }
#endif
  path.emplace_back("/var/lib/mfcd");
  path.emplace_back("/usr/share/mfcd");  // what the package ships (cell.yaml, camera-sim.yaml, web/)
  return path;
}

DaemonConfig parse_config(const std::string& yaml_text, const std::string& source, const std::vector<fs::path>& path) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw ConfigError(source, e.mark.line >= 0 ? e.mark.line + 1 : 0, "", "YAML syntax error: " + e.msg);
  }
  if (!root.IsDefined() || root.IsNull()) throw ConfigError(source, 0, "", "the file is empty");
  Context ctx{source, &path};
  DaemonConfig c;
  c.source = source;
  c.search_path = path;
  Section top(root, "", 1, ctx);

  read_daemon_section(top, c);
  read_camera_section(top, c);
  read_lights_section(top, c);
  read_sequencer_section(top, c);
  read_simulation_section(top, c);
  read_vision_section(top, c);
  read_recipes_section(top, c);
  read_pick_section(top, c);
  read_hand_eye_section(top, c);
  read_second_look_section(top, c);
  read_gripper_check_section(top, c);
  read_modbus_section(top, c);
  read_web_section(top, c);
  read_can_section(top, c);
  read_calibration_section(top, c);
  read_snapshots_section(top, c);
  top.finish();
  return c;
}

DaemonConfig load_config_file(const fs::path& file, const fs::path& data_dir) {
  std::ifstream in(file);
  if (!in) throw ConfigError(file.string(), 0, "", std::string("cannot read the file: ") + std::strerror(errno));
  std::stringstream text;
  text << in.rdbuf();
  return parse_config(text.str(), file.string(), search_path(fs::absolute(file).parent_path(), data_dir));
}

DaemonConfig load_embedded_config(const fs::path& data_dir) {
  return parse_config(embedded_sim_config(), "<embedded sim.yaml>", search_path({}, data_dir));
}

}  // namespace mfcd::daemon
