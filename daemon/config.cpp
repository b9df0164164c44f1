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
std::string configErrorText(const std::string& source, int line, const std::string& key, const std::string& reason) {
  std::string text = source;
  if (line > 0) text.append(":").append(std::to_string(line));
  text.append(": ");
  if (!key.empty()) text.append(key).append(": ");
  return text.append(reason);
}

}  // namespace

ConfigError::ConfigError(std::string source, int line, std::string key, const std::string& reason)
    : std::runtime_error(configErrorText(source, line, key, reason)),
      source_(std::move(source)),
      key_(std::move(key)),
      line_(line) {}

const char* toString(RunMode m) { return m == RunMode::Triggered ? "triggered" : "continuous"; }

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
bool runFromBuildTree() {
  std::error_code ec;
  const std::string exe = fs::read_symlink("/proc/self/exe", ec).string();
  const std::string build = std::string(MFCD_BUILD_DIR) + "/";
  return !ec && exe.rfind(build, 0) == 0 && exe.find("/usr/bin/", build.size() - 1) == std::string::npos;
}
}  // namespace
#endif

std::vector<fs::path> searchPath(const fs::path& configDir, const fs::path& dataDir) {
  std::vector<fs::path> path;
  if (!configDir.empty()) path.push_back(configDir);
  if (!dataDir.empty()) path.push_back(dataDir);
#ifdef MFCD_DEV_DATA_DIRS
  // Development runs from the build tree find the generated parts/templates, config/ and web/.
  if (runFromBuildTree()) {
    std::stringstream dev(MFCD_DEV_DATA_DIRS);
    for (std::string dir; std::getline(dev, dir, ':');)
      if (!dir.empty()) path.emplace_back(dir);
  }
#endif
  path.emplace_back("/var/lib/mfcd");
  path.emplace_back("/usr/share/mfcd");  // what the package ships (cell.yaml, camera-sim.yaml, web/)
  return path;
}

DaemonConfig parseConfig(const std::string& yamlText, const std::string& source, const std::vector<fs::path>& path) {
  YAML::Node root;
  try {
    root = YAML::Load(yamlText);
  } catch (const YAML::Exception& e) {
    throw ConfigError(source, e.mark.line >= 0 ? e.mark.line + 1 : 0, "", "YAML syntax error: " + e.msg);
  }
  if (!root.IsDefined() || root.IsNull()) throw ConfigError(source, 0, "", "the file is empty");
  Context ctx{source, &path};
  DaemonConfig c;
  c.source = source;
  c.search_path = path;
  Section top(root, "", 1, ctx);

  readDaemonSection(top, c);
  readCameraSection(top, c);
  readLightsSection(top, c);
  readSequencerSection(top, c);
  readSimulationSection(top, c);
  readVisionSection(top, c);
  readRecipesSection(top, c);
  readPickSection(top, c);
  readHandEyeSection(top, c);
  readSecondLookSection(top, c);
  readModbusSection(top, c);
  readWebSection(top, c);
  readCanSection(top, c);
  readCalibrationSection(top, c);
  readSnapshotsSection(top, c);
  top.finish();
  return c;
}

DaemonConfig loadConfigFile(const fs::path& file, const fs::path& dataDir) {
  std::ifstream in(file);
  if (!in) throw ConfigError(file.string(), 0, "", std::string("cannot read the file: ") + std::strerror(errno));
  std::stringstream text;
  text << in.rdbuf();
  return parseConfig(text.str(), file.string(), searchPath(fs::absolute(file).parent_path(), dataDir));
}

DaemonConfig loadEmbeddedConfig(const fs::path& dataDir) {
  return parseConfig(embeddedSimConfig(), "<embedded sim.yaml>", searchPath({}, dataDir));
}

}  // namespace mfcd::daemon
