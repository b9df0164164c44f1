// Faults at daemon level: what the environment does to a running mfcd (a full disk), answered
// with a clear error while the cell goes on.
#include <gtest/gtest.h>

#include <sys/mount.h>
#include <unistd.h>

#include "daemon_process.hpp"

using namespace mfcd::daemon::test;
using namespace std::chrono_literals;

TEST(DaemonFaults, AFullDiskFailsTheSnapshotWithTheReasonAndLeavesNoHalfSnapshot) {
  DaemonProcess proc("enospc");
  const fs::path small = proc.dir() / "small";
  fs::create_directories(small);
  // A 64 kB tmpfs: far too small for one snapshot (9 PNGs of 640 x 480), larger than its quota check.
  if (::geteuid() != 0 || ::mount("tmpfs", small.c_str(), "tmpfs", 0, "size=64k") != 0)
    GTEST_SKIP() << "needs root to mount a small tmpfs (CI runs as root)";
  struct Unmount {
    fs::path p;
    ~Unmount() { ::umount2(p.c_str(), MNT_DETACH); }
  } unmount{small};
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
