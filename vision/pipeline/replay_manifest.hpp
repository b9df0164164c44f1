#pragma once
// What a one-image BOP scene saved by mfcd (a snapshot, docs/operations.md "Snapshots") needs
// besides its images to be run again as the cycle ran it: the template files (by path, with
// size and CRC-32, so a changed file is refused rather than silently used), the vision
// pipeline's settings, the part type the cycle looked for, and which mfcd made it. Written as
// <root>/mfcd_replay.json beside the BOP files; mfc-detect reads it when it is there.
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace mfcd::vision {

struct PipelineConfig;

inline constexpr const char* kReplayManifestName = "mfcd_replay.json";

struct ReplayTemplate {
  std::filesystem::path path;  // as the daemon loaded it (absolute)
  std::uintmax_t bytes = 0;
  std::uint32_t crc32 = 0;  // zlib's CRC-32 of the whole file
};

struct ReplayManifest {
  std::string version, commit;  // of the mfcd that saved the scene
  std::uint64_t cycle = 0;
  int obj_id = 0;  // the part type the cycle looked for; 0 = every loaded type
  std::vector<ReplayTemplate> templates;
  // Every pipeline parameter (pipeline_parameters.hpp) by key, and the settings outside that
  // table that change a detection.
  std::map<std::string, double> parameters;
  std::vector<double> distances_mm;
  double floor_distance_mm = 0;
};

// The manifest of a pipeline configuration: the template files' sizes and CRCs are read now.
// Throws std::runtime_error naming a template file that cannot be read.
ReplayManifest make_replay_manifest(const PipelineConfig& config);
void write_replay_manifest(const ReplayManifest& manifest, const std::filesystem::path& file);
// Nullopt when `root` has no manifest; throws std::runtime_error naming the file and key when it
// is malformed.
std::optional<ReplayManifest> read_replay_manifest(const std::filesystem::path& root);

// The configuration the manifest describes, over `base`: every known parameter set (an unknown
// key, from another mfcd version, is listed in `ignored`), distances, floor, template files.
// Throws std::runtime_error when a template file is missing or differs (size or CRC) from the
// one the cycle used, naming it and saying how.
PipelineConfig replay_config(const ReplayManifest& manifest, PipelineConfig base, std::vector<std::string>& ignored);

std::uint32_t file_crc32(const std::filesystem::path& file);

}  // namespace mfcd::vision
