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
  void start_daemon(const std::string& name, int budget_ms = 1000, std::vector<std::string> env = {},
                    const std::string& extra = "") {
    start_daemon_on(
        name, [&](const fs::path& dir) { return sim_cell_config(dir, budget_ms, extra); }, std::move(env));
  }
  // The same on a configuration of the test's own, made for the process's folder.
  void start_daemon_on(const std::string& name, const std::function<std::string(const fs::path& dir)>& config,
                       std::vector<std::string> env = {}) {
    proc_ = std::make_unique<DaemonProcess>(name);
    proc_->write_config(config(proc_->dir()));
    proc_->start(MFCD_TEST_DAEMON, {}, std::move(env));
    if (!proc_->wait_ready()) {
      const std::string log = proc_->log();
      if (log.find("EGL") != std::string::npos || log.find("OpenGL") != std::string::npos)
        GTEST_SKIP() << "no offscreen OpenGL: " << log;
      FAIL() << "mfcd did not become ready:\n" << log;
    }
    port_ = proc_->modbus_port();
  }
  std::unique_ptr<DaemonProcess> proc_;
  int port_ = 0;
};

}  // namespace mfcd::daemon::test
