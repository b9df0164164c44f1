#pragma once
// Reading the daemon's YAML configuration (config.cpp, config_sections.cpp): a Section remembers
// which keys were read so that any other key is refused naming it and its line; one function per
// top-level section, in the order parse_config calls them (a later section may check an earlier
// one's values).
#include <yaml-cpp/yaml.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <set>
#include <string>
#include <vector>

#include "daemon/config.hpp"
#include "motion/pick_transform.hpp"

namespace mfcd::daemon::config_reader {

inline int line_of(const YAML::Node& n) { return n.IsDefined() && n.Mark().line >= 0 ? n.Mark().line + 1 : 0; }

struct Context {
  std::string source;
  const std::vector<fs::path>* search_path;
};

// One YAML mapping being read: remembers which keys were asked for so that any other key (a
// typo, a key from another version) is an error naming it.
class Section {
 public:
  Section(YAML::Node node, std::string path, int line, const Context& ctx)
      : node_(std::move(node)), path_(std::move(path)), line_(line), ctx_(ctx) {
    if (node_.IsDefined() && !node_.IsNull() && !node_.IsMap())
      fail(path_, line_of(node_), "must be a mapping of keys to values");
    if (node_.IsDefined() && !node_.IsNull()) line_ = line_of(node_);
  }

  [[noreturn]] void fail(const std::string& key, int line, const std::string& why) const {
    throw ConfigError(ctx_.source, line, key, why);
  }
  std::string key(const char* k) const {
    if (*k == '\0') return path_;
    return path_.empty() ? k : path_ + "." + k;
  }
  int line() const { return line_; }

  YAML::Node child(const char* k) {
    known_.insert(k);
    if (!node_.IsMap()) return YAML::Node(YAML::NodeType::Undefined);
    for (auto it = node_.begin(); it != node_.end(); ++it)
      if (it->first.Scalar() == k) return it->second;
    return YAML::Node(YAML::NodeType::Undefined);
  }
  bool has(const char* k) {
    YAML::Node n = child(k);
    return n.IsDefined() && !n.IsNull();
  }

  std::string scalar(const char* k, const YAML::Node& n) const {
    if (!n.IsScalar()) fail(key(k), line_of(n), "must be a single value");
    return n.Scalar();
  }

  long long integer(const char* k, long long def, long long min, long long max, bool required = false) {
    YAML::Node n = child(k);
    if (!n.IsDefined() || n.IsNull()) {
      if (required) fail(key(k), line_, "missing (required)");
      return def;
    }
    return to_integer(k, n, min, max);
  }
  long long to_integer(const char* k, const YAML::Node& n, long long min, long long max) const {
    const std::string s = scalar(k, n);
    errno = 0;
    char* end = nullptr;
    const long long v = std::strtoll(s.c_str(), &end, 0);
    if (s.empty() || *end != '\0' || errno == ERANGE) fail(key(k), line_of(n), "'" + s + "' is not an integer");
    if (v < min || v > max)
      fail(key(k), line_of(n),
           std::to_string(v) + " is out of range " + std::to_string(min) + ".." + std::to_string(max));
    return v;
  }
  double number(const char* k, double def, double min, double max) {
    YAML::Node n = child(k);
    if (!n.IsDefined() || n.IsNull()) return def;
    return to_number(k, n, min, max);
  }
  double to_number(const char* k, const YAML::Node& n, double min, double max) const {
    const std::string s = scalar(k, n);
    char* end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    if (s.empty() || *end != '\0' || !std::isfinite(v)) fail(key(k), line_of(n), "'" + s + "' is not a number");
    if (v < min || v > max) {
      std::ostringstream os;
      os << v << " is out of range " << min << ".." << max;
      fail(key(k), line_of(n), os.str());
    }
    return v;
  }
  bool boolean(const char* k, bool def) {
    YAML::Node n = child(k);
    if (!n.IsDefined() || n.IsNull()) return def;
    const std::string s = scalar(k, n);
    if (s == "true" || s == "yes" || s == "on") return true;
    if (s == "false" || s == "no" || s == "off") return false;
    fail(key(k), line_of(n), "'" + s + "' is not a boolean (true or false)");
  }
  std::string string(const char* k, const std::string& def, bool required = false) {
    YAML::Node n = child(k);
    if (!n.IsDefined() || n.IsNull()) {
      if (required) fail(key(k), line_, "missing (required)");
      return def;
    }
    const std::string s = scalar(k, n);
    if (s.empty()) fail(key(k), line_of(n), "must not be empty");
    return s;
  }
  template <typename E>
  E choice(const char* k, E def, std::initializer_list<std::pair<const char*, E>> options) {
    YAML::Node n = child(k);
    if (!n.IsDefined() || n.IsNull()) return def;
    const std::string s = scalar(k, n);
    std::string allowed;
    for (const auto& [name, value] : options) {
      if (s == name) return value;
      allowed += (allowed.empty() ? "" : ", ") + std::string(name);
    }
    fail(key(k), line_of(n), "'" + s + "' is not one of " + allowed);
  }
  // A path that must exist: absolute, or found in the search path (first match wins).
  fs::path file(const char* k, bool required) {
    YAML::Node n = child(k);
    if (!n.IsDefined() || n.IsNull()) {
      if (required) fail(key(k), line_, "missing (required)");
      return {};
    }
    const fs::path p = scalar(k, n);
    if (p.empty()) fail(key(k), line_of(n), "must not be empty");
    // The error_code overloads: a name the file system cannot even look up (ENAMETOOLONG, a
    // path through a file) is "not found" here, named with its key, not a filesystem_error.
    std::error_code ec;
    if (p.is_absolute()) {
      if (!fs::exists(p, ec))
        fail(key(k), line_of(n), "file " + p.string() + " does not exist" + (ec ? " (" + ec.message() + ")" : ""));
      return p;
    }
    std::string tried;
    for (const auto& dir : *ctx_.search_path) {
      const fs::path candidate = dir / p;
      if (fs::exists(candidate, ec)) return fs::absolute(candidate).lexically_normal();
      tried += (tried.empty() ? "" : ", ") + dir.string();
    }
    fail(key(k), line_of(n),
         "file '" + p.string() + "' not found in the search path (" + tried +
             "); give an absolute path or pass --data-dir");
  }
  Section section(const char* k) { return Section(child(k), key(k), line_, ctx_); }
  const Context& context() const { return ctx_; }

  void finish() const {
    if (!node_.IsMap()) return;
    for (auto it = node_.begin(); it != node_.end(); ++it) {
      const std::string name = it->first.Scalar();
      if (!known_.count(name)) fail(key(name.c_str()), line_of(it->first), "unknown key");
    }
  }

 private:
  YAML::Node node_;
  std::string path_;
  int line_;
  const Context& ctx_;
  std::set<std::string> known_;
};

inline Eigen::Isometry3d read_pose(Section& s) {
  motion::PoseXYZ p;
  p.position_mm = {s.number("x_mm", 0, -1e5, 1e5), s.number("y_mm", 0, -1e5, 1e5), s.number("z_mm", 0, -1e5, 1e5)};
  p.rotation = {s.number("rx_deg", 0, -360, 360), s.number("ry_deg", 0, -360, 360), s.number("rz_deg", 0, -360, 360)};
  s.finish();
  return motion::pose_to_isometry(p);
}

inline PoseSetting read_pose_setting(Section s, bool required) {
  if (required && !s.has("x_mm") && !s.has("y_mm") && !s.has("z_mm"))
    s.fail(s.key(""), s.line(), "missing (required): a pose {x_mm, y_mm, z_mm, rx_deg, ry_deg, rz_deg}");
  PoseSetting p;
  p.x_mm = s.number("x_mm", 0, -1e5, 1e5);
  p.y_mm = s.number("y_mm", 0, -1e5, 1e5);
  p.z_mm = s.number("z_mm", 0, -1e5, 1e5);
  p.rx_deg = s.number("rx_deg", 0, -360, 360);
  p.ry_deg = s.number("ry_deg", 0, -360, 360);
  p.rz_deg = s.number("rz_deg", 0, -360, 360);
  s.finish();
  return p;
}

void read_daemon_section(Section& top, DaemonConfig& c);
void read_camera_section(Section& top, DaemonConfig& c);
void read_lights_section(Section& top, DaemonConfig& c);
void read_sequencer_section(Section& top, DaemonConfig& c);
void read_simulation_section(Section& top, DaemonConfig& c);
void read_vision_section(Section& top, DaemonConfig& c);
void read_recipes_section(Section& top, DaemonConfig& c);
void read_pick_section(Section& top, DaemonConfig& c);
void read_hand_eye_section(Section& top, DaemonConfig& c);
void read_second_look_section(Section& top, DaemonConfig& c);
void read_gripper_check_section(Section& top, DaemonConfig& c);
void read_modbus_section(Section& top, DaemonConfig& c);
void read_web_section(Section& top, DaemonConfig& c);
void read_can_section(Section& top, DaemonConfig& c);
void read_calibration_section(Section& top, DaemonConfig& c);
void read_snapshots_section(Section& top, DaemonConfig& c);

}  // namespace mfcd::daemon::config_reader
