// mfcd with the test vision backend (TruthVisionStage) below VisionStage; everything else is the
// real daemon. MFCD_TEST_VISION_MS sets the backend's work time (default 20 ms);
// MFCD_TEST_VISION_HANG=1 makes it ignore the cycle's deadline (a hung vision stage);
// MFCD_TEST_VISION_FAIL_FIRST=N makes its first N cycles throw; MFCD_TEST_VISION_PATTERN=1 is for a
// cell whose camera serves the HAL test pattern (no meshes): every frame's tag is checked and one
// stand-in candidate is reported per cycle (test_vision_stage.hpp, "Pattern mode");
// MFCD_TEST_FAULTS=SEED,PERCENT injects camera and LED faults below the HAL before PERCENT % of the
// captures, drawn from SEED (fault_source.hpp).
#include <cstdio>
#include <cstdlib>

#include "daemon/daemon.hpp"
#include "fault_source.hpp"
#include "test_vision_stage.hpp"

int main(int argc, char** argv) {
  const char* ms = std::getenv("MFCD_TEST_VISION_MS");
  const std::chrono::milliseconds work(ms ? std::atoi(ms) : 20);
  const char* hang = std::getenv("MFCD_TEST_VISION_HANG");
  const char* fail = std::getenv("MFCD_TEST_VISION_FAIL_FIRST");
  const bool honour_deadline = !(hang && std::atoi(hang) != 0);
  const int fail_first = fail ? std::atoi(fail) : 0;
  const char* pattern = std::getenv("MFCD_TEST_VISION_PATTERN");
  const bool check_pattern = pattern && std::atoi(pattern) != 0;
  unsigned long long seed = 0;
  int percent = 0;
  if (const char* faults = std::getenv("MFCD_TEST_FAULTS")) std::sscanf(faults, "%llu,%d", &seed, &percent);
  const auto vision = [=](const mfcd::daemon::DaemonConfig&) {
    return std::make_unique<mfcd::daemon::test::TruthVisionStage>(work, honour_deadline, fail_first, check_pattern);
  };
  if (percent <= 0) return mfcd::daemon::daemon_main(argc, argv, vision);
  return mfcd::daemon::daemon_main(argc, argv, vision, [=](const mfcd::daemon::DaemonConfig& config) {
    return std::make_unique<mfcd::daemon::test::FaultySource>(mfcd::daemon::make_frame_source(config), seed, percent);
  });
}
