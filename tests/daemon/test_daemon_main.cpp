// mfcd with the test vision backend (TruthVisionStage) below VisionStage; everything else is the
// real daemon. MFCD_TEST_VISION_MS sets the backend's work time (default 20 ms).
#include <cstdlib>

#include "daemon/daemon.hpp"
#include "test_vision_stage.hpp"

int main(int argc, char** argv) {
  const char* ms = std::getenv("MFCD_TEST_VISION_MS");
  const std::chrono::milliseconds work(ms ? std::atoi(ms) : 20);
  return mfcd::daemon::daemonMain(argc, argv, [work](const mfcd::daemon::DaemonConfig&) {
    return std::make_unique<mfcd::daemon::test::TruthVisionStage>(work);
  });
}
