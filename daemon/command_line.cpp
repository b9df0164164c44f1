// mfcd's command line (docs/operations.md, "Running"), on tools/common/cli.hpp: --help and
// --version exit 0, a usage error exits 2 (as an invalid configuration does).
#include <cstdio>

#include "daemon/daemon.hpp"
#include "tools/common/cli.hpp"

namespace mfcd::daemon {

std::optional<DaemonOptions> parse_command_line(int argc, char** argv, int& exit_code) {
  CLI::App app{"mfcd: the vision daemon of the bin-picking cell (docs/operations.md).", "mfcd"};
  mfcd::tools::init_app(app);
  DaemonOptions o;
  app.add_option("-c,--config", o.config_file,
                 "configuration (default: the embedded config/sim.yaml, the simulated cell)")
      ->type_name("FILE");
  app.add_option("--data-dir", o.data_dir, "searched for relative paths after the config file's directory")
      ->type_name("DIR");
  app.add_flag("-f,--foreground", o.foreground, "also log to stderr");
  app.add_flag("--check-config", o.check_config,
               "validate the configuration (and its files) and exit: 0 valid, 2 invalid");
  app.add_flag("--leds-off", o.leds_off, "drive every LED line of the configuration off and exit (after a crash)");
  mfcd::tools::add_int(app, "--benchmark", o.benchmark_cycles,
                       "run N cycles back to back (no robot link), print cycle-time percentiles");
  app.add_option("--benchmark-json", o.benchmark_json, "also write them as JSON")->type_name("FILE");
  app.footer("Exit status: 0 clean stop, 1 runtime failure, 2 usage or configuration error.");
  if (const auto code = mfcd::tools::parse(app, argc, argv)) {
    exit_code = *code;
    return std::nullopt;
  }
  exit_code = 0;
  return o;
}

}  // namespace mfcd::daemon
