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
  std::filesystem::path config_file;  // empty: the embedded config/sim.yaml
  std::filesystem::path data_dir;
  bool foreground = false;    // also log to stderr
  bool check_config = false;  // validate the configuration and exit
  bool leds_off = false;      // drive every LED line off and exit (systemd ExecStopPost=)
  int benchmark_cycles = 0;   // > 0: run this many cycles without robot link, print stats, exit
  std::filesystem::path benchmark_json;
};

// Parses the command line (command_line.cpp; mfcd --help lists it). Returns nullopt when mfcd ends
// here: after --help or --version (`exit_code` 0) or a usage error (reported on stderr, 2).
std::optional<DaemonOptions> parse_command_line(int argc, char** argv, int& exit_code);

// Runs mfcd with `vision` as the vision backend factory (the real mfcd passes
// make_pipeline_stage). Returns the process exit code: 0 clean stop, 1 runtime failure,
// 2 configuration error.
// `source` builds the frame source (make_frame_source: the configuration's devices or the simulated
// cell; test daemons wrap it to inject faults below the HAL's interfaces).
int run_daemon(const DaemonOptions& options, const VisionStageFactory& vision,
               const FrameSourceFactory& source = make_frame_source);

// main() of mfcd and of test daemons that put another vision backend below VisionStage.
int daemon_main(int argc, char** argv, const VisionStageFactory& vision,
                const FrameSourceFactory& source = make_frame_source);

}  // namespace mfcd::daemon
