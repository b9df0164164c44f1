#pragma once
// mfcd's entry points. The daemon's main thread runs one event loop over the robot link's command
// eventfd, the cell's result eventfd, the control socket and its clients, a signalfd
// (SIGTERM/SIGINT/SIGHUP) and a timerfd (systemd watchdog, HEARTBEAT lease, status); it is the
// single writer of the robot link's reports. The class is in daemon_impl.hpp; see
// docs/operations.md.
#include <filesystem>
#include <optional>
#include <string>

#include "daemon/frame_source.hpp"
#include "daemon/vision_stage.hpp"

namespace mfcd::daemon {

struct DaemonOptions {
  std::filesystem::path configFile;  // empty: the embedded config/sim.yaml
  std::filesystem::path dataDir;
  bool foreground = false;   // also log to stderr
  bool checkConfig = false;  // validate the configuration and exit
  bool ledsOff = false;      // drive every LED line off and exit (systemd ExecStopPost=)
  int benchmarkCycles = 0;   // > 0: run this many cycles without robot link, print stats, exit
  std::filesystem::path benchmarkJson;
};

// Parses the command line (command_line.cpp; mfcd --help lists it). Returns nullopt when mfcd ends
// here: after --help or --version (`exitCode` 0) or a usage error (reported on stderr, 2).
std::optional<DaemonOptions> parseCommandLine(int argc, char** argv, int& exitCode);

// Runs mfcd with `vision` as the vision backend factory (the real mfcd passes
// makePipelineStage). Returns the process exit code: 0 clean stop, 1 runtime failure,
// 2 configuration error.
// `source` builds the frame source (makeFrameSource: the configuration's devices or the simulated
// cell; test daemons wrap it to inject faults below the HAL's interfaces).
int runDaemon(const DaemonOptions& options, const VisionStageFactory& vision,
              const FrameSourceFactory& source = makeFrameSource);

// main() of mfcd and of test daemons that put another vision backend below VisionStage.
int daemonMain(int argc, char** argv, const VisionStageFactory& vision,
               const FrameSourceFactory& source = makeFrameSource);

}  // namespace mfcd::daemon
