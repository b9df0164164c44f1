#include "vision/pipeline/replay_manifest.hpp"

#include <zlib.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "vision/pipeline/bin_picking_pipeline.hpp"
#include "vision/pipeline/pipeline_parameters.hpp"

namespace mfcd::vision {

namespace fs = std::filesystem;
using nlohmann::json;

std::uint32_t file_crc32(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error(file.string() + ": cannot read");
  uLong crc = crc32(0L, Z_NULL, 0);
  char buf[1 << 16];
  while (in) {
    in.read(buf, sizeof buf);
    const std::streamsize n = in.gcount();
    if (n > 0) crc = crc32(crc, reinterpret_cast<const Bytef*>(buf), static_cast<uInt>(n));
  }
  if (in.bad()) throw std::runtime_error(file.string() + ": read error");
  return static_cast<std::uint32_t>(crc);
}

ReplayManifest make_replay_manifest(const PipelineConfig& config) {
  ReplayManifest m;
  for (const fs::path& f : config.template_files) {
    std::error_code ec;
    const fs::path path = fs::absolute(f, ec);
    const std::uintmax_t bytes = fs::file_size(path, ec);
    if (ec) throw std::runtime_error(path.string() + ": " + ec.message());
    m.templates.push_back({path, bytes, file_crc32(path)});
  }
  for (const PipelineParameter& p : pipeline_parameters()) m.parameters[p.key] = p.get(config);
  m.distances_mm = config.distances_mm;
  m.floor_distance_mm = config.floor.distance_mm;
  return m;
}

void write_replay_manifest(const ReplayManifest& m, const fs::path& file) {
  json templates = json::array();
  for (const ReplayTemplate& t : m.templates) {
    char crc[16];
    std::snprintf(crc, sizeof crc, "%08x", t.crc32);
    templates.push_back({{"path", t.path.string()}, {"bytes", t.bytes}, {"crc32", crc}});
  }
  const json j = {{"mfcd_version", m.version},
                  {"mfcd_commit", m.commit},
                  {"cycle", m.cycle},
                  {"obj_id", m.obj_id},
                  {"templates", templates},
                  {"parameters", m.parameters},
                  {"search_distances_mm", m.distances_mm},
                  {"floor_distance_mm", m.floor_distance_mm}};
  std::ofstream out(file);
  out << j.dump(2) << "\n";
  out.close();
  if (out.fail()) throw std::runtime_error(file.string() + ": cannot write");
}

namespace {

[[noreturn]] void malformed(const fs::path& file, const std::string& why) {
  throw std::runtime_error(file.string() + ": " + why);
}

}  // namespace

std::optional<ReplayManifest> read_replay_manifest(const fs::path& root) {
  const fs::path file = root / kReplayManifestName;
  if (!fs::exists(file)) return std::nullopt;
  std::ifstream in(file);
  json j;
  try {
    j = json::parse(in);
  } catch (const json::exception& e) {
    malformed(file, std::string("not JSON: ") + e.what());
  }
  if (!j.is_object()) malformed(file, "top level is not a JSON object");
  ReplayManifest m;
  try {
    m.version = j.value("mfcd_version", "");
    m.commit = j.value("mfcd_commit", "");
    m.cycle = j.value("cycle", std::uint64_t{0});
    m.obj_id = j.at("obj_id").get<int>();
    for (const json& t : j.at("templates")) {
      ReplayTemplate r;
      r.path = t.at("path").get<std::string>();
      r.bytes = t.at("bytes").get<std::uintmax_t>();
      const std::string crc = t.at("crc32").get<std::string>();
      std::size_t used = 0;
      r.crc32 = static_cast<std::uint32_t>(std::stoul(crc, &used, 16));
      if (used != crc.size()) malformed(file, "templates: crc32 '" + crc + "' is not hexadecimal");
      m.templates.push_back(r);
    }
    for (const auto& [key, v] : j.at("parameters").items()) m.parameters[key] = v.get<double>();
    m.distances_mm = j.value("search_distances_mm", std::vector<double>{});
    m.floor_distance_mm = j.value("floor_distance_mm", 0.0);
  } catch (const json::exception& e) {
    malformed(file, std::string("malformed: ") + e.what());
  } catch (const std::invalid_argument&) {
    malformed(file, "templates: a crc32 is not hexadecimal");
  }
  return m;
}

PipelineConfig replay_config(const ReplayManifest& m, PipelineConfig config, std::vector<std::string>& ignored) {
  for (const auto& [key, value] : m.parameters) {
    if (!find_pipeline_parameter(key)) {
      ignored.push_back(key);
      continue;
    }
    set_pipeline_parameter(config, key, value);
  }
  config.distances_mm = m.distances_mm;
  config.floor.distance_mm = m.floor_distance_mm;
  config.template_files.clear();
  for (const ReplayTemplate& t : m.templates) {
    std::error_code ec;
    const std::uintmax_t bytes = fs::file_size(t.path, ec);
    if (ec) throw std::runtime_error(t.path.string() + ": the cycle's template file cannot be read: " + ec.message());
    const std::uint32_t crc = bytes == t.bytes ? file_crc32(t.path) : 0;
    if (bytes != t.bytes || crc != t.crc32) {
      char what[128];
      std::snprintf(what, sizeof what, "%ju bytes, CRC-32 %08x; the cycle used %ju bytes, CRC-32 %08x", bytes, crc,
                    t.bytes, t.crc32);
      throw std::runtime_error(t.path.string() + ": not the template file the cycle used (now " + what +
                               "); give the cycle's file with --templates");
    }
    config.template_files.push_back(t.path);
  }
  return config;
}

}  // namespace mfcd::vision
