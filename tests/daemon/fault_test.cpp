// Faults at daemon level: what the environment does to a running mfcd (a full disk), answered
// with a clear error while the cell goes on.
#include <gtest/gtest.h>

#include "daemon_process.hpp"

using namespace mfcd::daemon::test;
using namespace std::chrono_literals;

TEST(DaemonFaults, AFullDiskFailsTheSnapshotWithTheReasonAndLeavesNoHalfSnapshot) {
  DaemonProcess proc("enospc");
  // 64 kB: far too small for one snapshot (9 PNGs of 640 x 480), larger than its quota check.
  const SmallDisk disk(proc.dir() / "small", "64k");
  if (!disk.mounted()) GTEST_SKIP() << SmallDisk::kSkipReason;
  const fs::path& small = disk.dir();
  std::string config = sim_cell_config(proc.dir());
  const std::string from = "snapshots:\n  directory: " + (proc.dir() / "snapshots").string();
  config.replace(config.find(from), from.size(), "snapshots:\n  directory: " + small.string());
  proc.write_config(config);
  proc.start(MFCD_TEST_DAEMON);
  if (!proc.wait_ready()) {
    const std::string log = proc.log();
    if (log.find("EGL") != std::string::npos || log.find("OpenGL") != std::string::npos)
      GTEST_SKIP() << "no offscreen OpenGL";
    FAIL() << log;
  }
  const json snap = proc.ctl({{"cmd", "snapshot"}, {"recipe", 0}});
  EXPECT_EQ(snap["ok"], false) << snap.dump();
  EXPECT_NE(snap.value("error", "").find("no space left"), std::string::npos) << snap.dump();
  std::size_t left = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(small)) ++left;
  EXPECT_EQ(left, 0u) << "the half-written snapshot directory is removed";
  // The cell goes on: a cycle without a snapshot works.
  const json r = proc.ctl({{"cmd", "trigger"}, {"recipe", 0}});
  EXPECT_EQ(r["ok"], true) << r.dump();
  proc.signal(SIGTERM);
  EXPECT_EQ(proc.wait(10000), 0);
}
