// The replay manifest of an mfcd snapshot: written and read back, applied to a configuration, and
// a template file that changed since the cycle refused with the reason.
#include "vision/pipeline/replay_manifest.hpp"

#include <gtest/gtest.h>
#include <zlib.h>

#include <unistd.h>
#include <fstream>
#include <string>

#include "vision/pipeline/bin_picking_pipeline.hpp"

using namespace mfcd::vision;
namespace fs = std::filesystem;

namespace {

struct TempDir {
  fs::path path = fs::temp_directory_path() / ("mfcd-replay-" + std::to_string(::getpid()));
  TempDir() { fs::create_directories(path); }
  ~TempDir() { fs::remove_all(path); }
};

void writeBytes(const fs::path& file, const std::string& bytes) { std::ofstream(file, std::ios::binary) << bytes; }

}  // namespace

TEST(ReplayManifest, Crc32IsZlibsOverTheWholeFile) {
  TempDir tmp;
  std::string bytes(200000, '\0');
  for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<char>((i * 7919) & 0xff);
  writeBytes(tmp.path / "a.bin", bytes);
  // The slow twin: one call over the whole buffer (file_crc32 reads in 64 KiB chunks).
  const auto whole = static_cast<std::uint32_t>(
      crc32(0L, reinterpret_cast<const Bytef*>(bytes.data()), static_cast<uInt>(bytes.size())));
  EXPECT_EQ(file_crc32(tmp.path / "a.bin"), whole);
  writeBytes(tmp.path / "check.bin", "123456789");
  EXPECT_EQ(file_crc32(tmp.path / "check.bin"), 0xCBF43926u) << "the CRC-32 check value";
}

TEST(ReplayManifest, RoundTripsAndSetsTheCyclesConfiguration) {
  TempDir tmp;
  writeBytes(tmp.path / "part.tdb", "template bytes");
  PipelineConfig cycle;
  cycle.template_files = {tmp.path / "part.tdb"};
  cycle.search_rounds = 3;
  cycle.max_candidates = 5;
  cycle.distances_mm = {400, 450};
  cycle.floor.distance_mm = 512;
  ReplayManifest m = make_replay_manifest(cycle);
  m.cycle = 42;
  m.obj_id = 4;
  m.version = "1.2.3";
  m.parameters["a_key_from_another_version"] = 1;
  write_replay_manifest(m, tmp.path / kReplayManifestName);

  const auto back = read_replay_manifest(tmp.path);
  ASSERT_TRUE(back);
  EXPECT_EQ(back->cycle, 42u);
  EXPECT_EQ(back->obj_id, 4);
  EXPECT_EQ(back->version, "1.2.3");
  ASSERT_EQ(back->templates.size(), 1u);
  EXPECT_EQ(back->templates[0].bytes, 14u);
  EXPECT_EQ(back->templates[0].crc32, file_crc32(tmp.path / "part.tdb"));

  std::vector<std::string> ignored;
  const PipelineConfig replay = replay_config(*back, PipelineConfig{}, ignored);
  EXPECT_EQ(replay.search_rounds, 3);
  EXPECT_EQ(replay.max_candidates, 5);
  EXPECT_EQ(replay.distances_mm, (std::vector<double>{400, 450}));
  EXPECT_EQ(replay.floor.distance_mm, 512);
  EXPECT_EQ(replay.template_files, cycle.template_files);
  EXPECT_EQ(ignored, (std::vector<std::string>{"a_key_from_another_version"}));
  EXPECT_FALSE(read_replay_manifest(tmp.path / "nowhere")) << "no manifest: not a snapshot";
}

TEST(ReplayManifest, AChangedTemplateFileOrAMalformedManifestIsRefusedWithTheReason) {
  TempDir tmp;
  writeBytes(tmp.path / "part.tdb", "template bytes");
  PipelineConfig cycle;
  cycle.template_files = {tmp.path / "part.tdb"};
  write_replay_manifest(make_replay_manifest(cycle), tmp.path / kReplayManifestName);
  const ReplayManifest m = *read_replay_manifest(tmp.path);
  std::vector<std::string> ignored;
  writeBytes(tmp.path / "part.tdb", "template bytez");  // same size, other bytes
  try {
    replay_config(m, PipelineConfig{}, ignored);
    ADD_FAILURE() << "a changed template file was used";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("not the template file the cycle used"), std::string::npos) << e.what();
  }
  fs::remove(tmp.path / "part.tdb");
  EXPECT_THROW(replay_config(m, PipelineConfig{}, ignored), std::runtime_error);
  writeBytes(tmp.path / kReplayManifestName, "{\"obj_id\": 1, \"templates\": [{\"path\": \"x\"}]}");
  try {
    read_replay_manifest(tmp.path);
    ADD_FAILURE() << "a manifest without a template's size was read";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(kReplayManifestName), std::string::npos) << e.what();
  }
}
