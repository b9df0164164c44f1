// mfcd_journal_probe CYCLE JOB: opens the log the way mfcd does (log_open: journal sink when
// $JOURNAL_STREAM names stderr) and logs the three sample cycle results of journal_samples.hpp
// (cycles CYCLE, CYCLE+1, CYCLE+2, job JOB) with log_cycle_result, as Daemon::on_result does. Prints
// "probe job JOB: journal sink open|closed" on stdout. Run under a journald by
// journal_roundtrip.sh for the JournalRoundTrip test. Exit 0, or 2 on bad arguments.
#include <cstdio>
#include <cstdlib>

#include "daemon/journal_log.hpp"
#include "journal_samples.hpp"

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: mfcd_journal_probe CYCLE JOB\n");
    return 2;
  }
  using namespace mfcd::daemon;
  const auto cycle = std::strtoull(argv[1], nullptr, 10);
  const auto job = static_cast<std::uint16_t>(std::strtoul(argv[2], nullptr, 10));
  // As `mfcd -f`: stderr on. Under journald the cycle lines must still not appear there.
  log_open("mfcd", true, LogLevel::Info);
  std::printf("probe job %u: journal sink %s\n", static_cast<unsigned>(job), log_to_journal() ? "open" : "closed");
  std::fflush(stdout);
  log_cycle_result(test::error_result(cycle, job));
  log_cycle_result(test::pick_result(cycle + 1, job));
  log_cycle_result(test::no_pick_result(cycle + 2, job));
  return 0;
}
