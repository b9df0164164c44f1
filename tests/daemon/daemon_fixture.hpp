#pragma once
// A test with the real daemon running on the simulated cell: started on a test configuration,
// ready, its Modbus port known; skipped with the reason where offscreen OpenGL is missing.
#include <gtest/gtest.h>

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "daemon_process.hpp"

namespace mfcd::daemon::test {

class DaemonFixture : public ::testing::Test {
 protected:
  void startDaemon(const std::string& name, int budgetMs = 1000, std::vector<std::string> env = {},
                   const std::string& extra = "") {
    startDaemonOn(
        name, [&](const fs::path& dir) { return simCellConfig(dir, budgetMs, extra); }, std::move(env));
  }
  // The same on a configuration of the test's own, made for the process's folder.
  void startDaemonOn(const std::string& name, const std::function<std::string(const fs::path& dir)>& config,
                     std::vector<std::string> env = {}) {
    proc = std::make_unique<DaemonProcess>(name);
    proc->writeConfig(config(proc->dir()));
    proc->start(MFCD_TEST_DAEMON, {}, std::move(env));
    if (!proc->waitReady()) {
      const std::string log = proc->log();
      if (log.find("EGL") != std::string::npos || log.find("OpenGL") != std::string::npos)
        GTEST_SKIP() << "no offscreen OpenGL: " << log;
      FAIL() << "mfcd did not become ready:\n" << log;
    }
    port = proc->modbusPort();
  }
  std::unique_ptr<DaemonProcess> proc;
  int port = 0;
};

}  // namespace mfcd::daemon::test
