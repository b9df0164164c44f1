// mfcd's command line (docs/operations.md, "Running"), on tools/common/cli.hpp: --help and
// --version exit 0, a usage error exits 2 (as an invalid configuration does).
#include <cstdio>

#include "daemon/daemon.hpp"
#include "tools/common/cli.hpp"

namespace mfcd::daemon {

std::optional<DaemonOptions> parseCommandLine(int argc, char** argv, int& exitCode) {
  CLI::App app{"mfcd: the vision daemon of the bin-picking cell (docs/operations.md).", "mfcd"};
  mfcd::tools::init_app(app);
  DaemonOptions o;
  app.add_option("-c,--config", o.configFile,
                 "configuration (default: the embedded config/sim.yaml, the simulated cell)")
      ->type_name("FILE");
  app.add_option("--data-dir", o.dataDir, "searched for relative paths after the config file's directory")
      ->type_name("DIR");
  app.add_flag("-f,--foreground", o.foreground, "also log to stderr");
  app.add_flag("--check-config", o.checkConfig,
               "validate the configuration (and its files) and exit: 0 valid, 2 invalid");
  app.add_flag("--leds-off", o.ledsOff, "drive every LED line of the configuration off and exit (after a crash)");
  mfcd::tools::add_int(app, "--benchmark", o.benchmarkCycles,
                       "run N cycles back to back (no robot link), print cycle-time percentiles");
  app.add_option("--benchmark-json", o.benchmarkJson, "also write them as JSON")->type_name("FILE");
  app.footer("Exit status: 0 clean stop, 1 runtime failure, 2 usage or configuration error.");
  if (const auto code = mfcd::tools::parse(app, argc, argv)) {
    exitCode = *code;
    return std::nullopt;
  }
  exitCode = 0;
  return o;
}

}  // namespace mfcd::daemon
