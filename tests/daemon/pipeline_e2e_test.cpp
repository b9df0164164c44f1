// The real mfcd (vision backend = BinPickingPipeline over the generated .tdb templates) on the
// simulated cell: a libmodbus PLC client triggers cycles and the published picks must lie on the
// simulated parts (ground truth from the control socket) within tolerance (2 mm lateral, 8 mm in
// depth), of the reported part type, within the budget.
#include <gtest/gtest.h>

#include <array>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include <modbus/modbus.h>

#include "daemon_process.hpp"
#include "motion/float_codec.hpp"
#include "motion/register_map.hpp"
#include "pipeline_templates.hpp"

using namespace mfcd::daemon::test;
using namespace mfcd::motion;
using namespace std::chrono_literals;

namespace {
// Lateral position comes straight from the image (0.27 mm/px at the floor); depth along the optical
// axis from the refined scale, which is less certain for a single view.
constexpr double kLateralToleranceMm = 2.0;
constexpr double kDepthToleranceMm = 8.0;
// Recipe 0 searches all six part types (1,115 template views): 0.6-1.0 s of vision on this
// shared 2-core machine, so the budget here is 3 s (config/sim.yaml: 2 s).
constexpr int kBudgetMs = 3000;

}  // namespace

TEST(PipelineE2E, RealMfcdPicksSimulatedPartsWithinToleranceAndBudget) {
#ifndef MFCD_HAVE_PIPELINE
  GTEST_SKIP() << "mfcd was built without vision/pipeline (mfcd_vision_pipeline): no real vision backend yet";
#else
  if (const std::string missing = missing_template(); !missing.empty()) GTEST_SKIP() << missing;
  DaemonProcess proc("pipeline");
  // Two search rounds (vision.search_rounds), as config/sim.yaml has them.
  proc.write_config(sim_cell_config(proc.dir(), kBudgetMs, "", true) + "vision:\n  search_rounds: 2\n");
  proc.start(MFCD_BINARY);
  ASSERT_TRUE(proc.wait_ready(180000)) << proc.log();
  modbus_t* ctx = modbus_new_tcp("127.0.0.1", proc.modbus_port());
  ASSERT_EQ(modbus_connect(ctx), 0);
  modbus_set_response_timeout(ctx, 3, 0);
  std::uint16_t regs[28];
  auto at = [&](int a) { return regs[a - reg::kStatus]; };
  auto f = [&](int a) { return decode_float(at(a), at(a + 1), WordOrder::ABCD); };
  int matched = 0, picks = 0, degraded = 0, two_rounds = 0;
  for (std::uint16_t job = 1; job <= 6; ++job) {
    for (int i = 0; i < 2000; ++i) {
      ASSERT_EQ(modbus_read_registers(ctx, reg::kStatus, 28, regs), 28);
      if (at(reg::kStatus) & reg::kReady) break;
      std::this_thread::sleep_for(5ms);
    }
    const std::uint16_t cmd[4] = {1, job, 0, 0};
    ASSERT_EQ(modbus_write_registers(ctx, reg::kCommand, 4, cmd), 4) << modbus_strerror(errno);
    bool done = false;
    for (int i = 0; i < 6000 && !done; ++i) {
      ASSERT_EQ(modbus_read_registers(ctx, reg::kStatus, 28, regs), 28);
      done = at(reg::kJobIdEcho) == job;
      if (!done) std::this_thread::sleep_for(5ms);
    }
    ASSERT_TRUE(done) << proc.log();
    ASSERT_EQ(at(reg::kErrorCode), 0) << proc.log();
    EXPECT_LE(at(reg::kCycleTimeMs), kBudgetMs) << "job " << job;
    const json last = proc.ctl({{"cmd", "last"}})["result"];
    const int rounds = last["search_rounds"].get<int>();
    // Whether the pipeline's wide search ran (vision.escalate_below) is reported with every cycle.
    EXPECT_TRUE(last.contains("escalated") && last["escalated"].is_boolean()) << "job " << job << ": " << last.dump();
    EXPECT_TRUE(rounds == 1 || rounds == 2) << "job " << job << ": " << rounds << " search rounds";
    degraded += last["degraded"].get<bool>();
    two_rounds += rounds == 2;
    if (!(at(reg::kStatus) & reg::kPickValid)) {
      std::string found;
      for (const auto& c : last["candidates"])
        found +=
            " obj " + std::to_string(c["obj_id"].get<int>()) + " score " + std::to_string(c["score"].get<double>());
      std::string truth;
      for (const auto& t : last["sim_truth"]) truth += " " + std::to_string(t["obj_id"].get<int>());
      ADD_FAILURE() << "job " << job << ": no pick; candidates:" << found << "; parts in the bin (obj ids):" << truth
                    << "; degraded " << last["degraded"] << ", " << last["times_ms"]["total"] << " ms";
      continue;
    }
    ++picks;
    const double x = f(reg::kPickX), y = f(reg::kPickY), z = f(reg::kPickZ);
    double best = 1e9, dxy = 0, dz = 0;
    int truth_obj = 0;
    for (const auto& t : last["sim_truth"]) {
      const double ex = t["base"]["x"].get<double>() - x, ey = t["base"]["y"].get<double>() - y,
                   ez = t["base"]["z"].get<double>() - z;
      const double d = std::sqrt(ex * ex + ey * ey + ez * ez);
      if (d < best) best = d, truth_obj = t["obj_id"].get<int>(), dxy = std::hypot(ex, ey), dz = ez;
    }
    std::printf(
        "job %u: pick %.1f %.1f %.1f obj %d score %.2f; nearest part obj %d: %.2f mm (xy %.2f, z %+.2f); cycle %u "
        "ms%s\n",
        job, x, y, z, last["pick"]["obj_id"].get<int>(), f(reg::kScore), truth_obj, best, dxy, dz,
        at(reg::kCycleTimeMs), last["degraded"].get<bool>() ? " degraded" : "");
    if (dxy <= kLateralToleranceMm && std::abs(dz) <= kDepthToleranceMm &&
        truth_obj == last["pick"]["obj_id"].get<int>())
      ++matched;
  }
  modbus_close(ctx);
  modbus_free(ctx);
  // Measured (seed 1 bin), release and ASan (degraded by the deadline): all 6 picks on a part of
  // the reported type, within 0.4 mm laterally and 1.4 mm in depth (before the hypothesis fit an
  // ellipse was picked 35-40 mm too deep every time). One pick of slack for a slower machine,
  // where the deadline cuts the search shorter.
  EXPECT_GE(matched, 5) << "picks on a simulated part of the reported type within tolerance";
  EXPECT_EQ(picks, 6);
  // A second round runs when the first was complete and the budget leaves it room (release: every
  // cycle; under ASan the deadline degrades the first round, and then no second runs).
  std::printf("%d of 6 cycles degraded, %d ran two search rounds\n", degraded, two_rounds);
  if (degraded == 0) {
    EXPECT_GT(two_rounds, 0) << "no cycle ran its second search round";
  }
  proc.signal(SIGTERM);
  EXPECT_EQ(proc.wait(15000), 0);
#endif
}

namespace {

struct CsvEstimate {
  int obj_id = 0;
  double score = 0;
  std::array<double, 9> R{};
  std::array<double, 3> t{};
};

// The rows of a BOP results CSV (vision/dataset/bop_results.hpp): scene_id,im_id,obj_id,score,R,t,time.
std::vector<CsvEstimate> read_bop_csv(const fs::path& file) {
  std::ifstream in(file);
  std::string line;
  std::getline(in, line);  // header
  std::vector<CsvEstimate> out;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream row(line);
    for (std::string cell; std::getline(row, cell, ',');) f.push_back(cell);
    if (f.size() != 7) continue;
    CsvEstimate e;
    e.obj_id = std::stoi(f[2]);
    e.score = std::stod(f[3]);
    std::stringstream R(f[4]), t(f[5]);
    for (double& v : e.R) R >> v;
    for (double& v : e.t) t >> v;
    out.push_back(e);
  }
  return out;
}

}  // namespace

// A snapshot is a one-image BOP scene with the cycle's settings and template files
// (mfcd_replay.json): mfc-detect on it gives the cycle's candidates again, pose for pose.
TEST(PipelineE2E, SnapshotReplaysToTheSameCandidates) {
#ifndef MFCD_HAVE_PIPELINE
  GTEST_SKIP() << "mfcd was built without vision/pipeline (mfcd_vision_pipeline): no real vision backend yet";
#else
  if (const std::string missing = missing_template(); !missing.empty()) GTEST_SKIP() << missing;
  DaemonProcess proc("replay");
  // A budget no machine reaches (ASan included): the cycle runs to its end, as mfc-detect does.
  proc.write_config(sim_cell_config(proc.dir(), 60000, "", true) + "vision:\n  search_rounds: 2\n");
  proc.start(MFCD_BINARY);
  ASSERT_TRUE(proc.wait_ready(180000)) << proc.log();
  const json snap = proc.ctl({{"cmd", "snapshot"}, {"recipe", 0}}, 120000);
  ASSERT_TRUE(snap.value("ok", false)) << snap.dump() << proc.log();
  const fs::path dir = snap["snapshot"].get<std::string>();
  const json result = snap["result"];
  ASSERT_FALSE(result["degraded"].get<bool>()) << "the cycle was cut short: nothing to compare";
  ASSERT_GT(result["candidates"].size(), 0u);
  for (const char* f :
       {"mfcd_replay.json", "camera.json", "camera.yaml", "mfcd.yaml", "test/000001/scene_camera.json",
        "test/000001/scene_gt.json", "test/000001/flash/000000_7.png", "test/000001/ambient/000000.png"})
    EXPECT_TRUE(fs::exists(dir / f)) << f;

  const fs::path csv = proc.dir() / "replay_mfcsnap-test.csv";
  const std::string cmd = std::string(MFC_DETECT_BINARY) + " --dataset " + dir.string() + " --out " + csv.string() +
                          " --quiet > " + (proc.dir() / "detect.log").string() + " 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  const std::vector<CsvEstimate> replayed = read_bop_csv(csv);
  const json& cands = result["candidates"];
  ASSERT_EQ(replayed.size(), cands.size()) << "the replay found another number of candidates";
  for (std::size_t i = 0; i < replayed.size(); ++i) {
    const json& c = cands[i];
    EXPECT_EQ(replayed[i].obj_id, c["obj_id"].get<int>()) << "candidate " << i;
    EXPECT_NEAR(replayed[i].score, c["score"].get<double>(), 1e-4) << "candidate " << i;
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(replayed[i].t[k], c["t_cam_mm"][k].get<double>(), 1e-3) << "candidate " << i;
    for (int k = 0; k < 9; ++k) EXPECT_NEAR(replayed[i].R[k], c["R_cam"][k].get<double>(), 1e-5) << "candidate " << i;
  }
  proc.signal(SIGTERM);
  EXPECT_EQ(proc.wait(15000), 0);
#endif
}
