// mfc-plc-client: a PLC stand-in for demos. Triggers N pick cycles on mfcd over Modbus/TCP with
// the job-id handshake of docs/register-map.md (libmodbus client) and prints each pick.
#include <modbus/modbus.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <thread>

#include "motion/float_codec.hpp"
#include "motion/register_map.hpp"
#include "tools/common/cli.hpp"

using namespace mfcd::motion;
using namespace std::chrono_literals;

namespace {

struct Snapshot {
  std::uint16_t regs[28];
  std::uint16_t at(int addr) const { return regs[addr - reg::kStatus]; }
  float f(int addr, WordOrder o) const { return decode_float(at(addr), at(addr + 1), o); }
};

bool read_status(modbus_t* ctx, Snapshot& s) { return modbus_read_registers(ctx, reg::kStatus, 28, s.regs) == 28; }

struct Options {
  std::string host = "127.0.0.1";
  int port = 1502, cycles = 5, recipe = 0, mode = 0, first_job = 0, timeout_ms = 10000, connect_ms = 30000;
};

// The command line into `o`; the exit status when the program ends here (help, version, usage).
std::optional<int> parse_options(int argc, char** argv, Options& o) {
  CLI::App app{
      "mfc-plc-client: triggers N cycles on mfcd over Modbus/TCP (the job-id handshake of\n"
      "docs/register-map.md) and prints each pick: job, recipe, x y z [mm] rx ry rz [deg] in the robot\n"
      "base frame, score, cycle time [ms].",
      "mfc-plc-client"};
  mfcd::tools::init_app(app);
  app.add_option("--host", o.host, "mfcd's address (default 127.0.0.1)")->type_name("H");
  mfcd::tools::add_int(app, "--port", o.port, "Modbus/TCP port (default 1502)")->type_name("P");
  mfcd::tools::add_int(app, "--cycles", o.cycles, "cycles to trigger (default 5)");
  mfcd::tools::add_int(app, "--recipe", o.recipe, "RECIPE_ID of every trigger (default 0)")->type_name("R");
  app.add_flag_callback(
      "--count-only", [&o] { o.mode = 1; }, "MODE = COUNT_ONLY (objects remaining, no pick)");
  mfcd::tools::add_int(app, "--first-job", o.first_job, "the first job id (default: one past the last echoed)")
      ->type_name("J");
  mfcd::tools::add_int(app, "--timeout-ms", o.timeout_ms, "how long one cycle may take (default 10000)")
      ->type_name("T");
  mfcd::tools::add_int(app, "--connect-timeout-ms", o.connect_ms,
                       "retries the connection while mfcd starts (default 30000)")
      ->type_name("T");
  app.footer("Exit status: 0 all cycles answered, 1 a cycle failed or timed out, 2 usage/connection.");
  return mfcd::tools::parse(app, argc, argv);
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  if (const auto code = parse_options(argc, argv, o)) return *code;
  const std::string& host = o.host;
  const int port = o.port, cycles = o.cycles, recipe = o.recipe, mode = o.mode, first_job = o.first_job,
            timeout_ms = o.timeout_ms, connect_ms = o.connect_ms;
  // mfcd may still be starting (loading templates): retry the connection for a while.
  // Owned: freed on every return, also the error paths.
  const std::unique_ptr<modbus_t, decltype(&modbus_free)> context(modbus_new_tcp(host.c_str(), port), &modbus_free);
  modbus_t* ctx = context.get();
  bool connected = false;
  for (const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(connect_ms);;) {
    connected = ctx && modbus_connect(ctx) == 0;
    if (connected || std::chrono::steady_clock::now() > until) break;
    std::this_thread::sleep_for(200ms);
  }
  if (!connected) {
    std::fprintf(stderr, "mfc-plc-client: cannot connect to %s:%d: %s\n", host.c_str(), port, modbus_strerror(errno));
    return 2;
  }
  modbus_set_response_timeout(ctx, 2, 0);
  Snapshot s{};
  if (!read_status(ctx, s)) {
    std::fprintf(stderr, "mfc-plc-client: reading the status block: %s\n", modbus_strerror(errno));
    return 2;
  }
  const WordOrder order = s.at(reg::kWordOrder) == 1 ? WordOrder::CDAB : WordOrder::ABCD;
  // A new job id: one past the last echoed, skipping 0 (the server refuses a repeated id).
  std::uint16_t job = static_cast<std::uint16_t>(first_job ? first_job : s.at(reg::kJobIdEcho) + 1);
  if (job == 0) job = 1;
  std::printf("%6s %6s %9s %9s %9s %8s %8s %8s %6s %8s %s\n", "job", "recipe", "x", "y", "z", "rx", "ry", "rz", "score",
              "cycle_ms", "part/objects");
  int failures = 0;
  for (int c = 0; c < cycles; ++c, job = static_cast<std::uint16_t>(job == 65535 ? 1 : job + 1)) {
    const auto start = std::chrono::steady_clock::now();
    const auto expired = [&] {
      return std::chrono::steady_clock::now() - start > std::chrono::milliseconds(timeout_ms);
    };
    // 1. wait for READY; 2-3. trigger in one FC 0x10 write.
    bool triggered = false;
    while (!triggered && !expired()) {
      if (!read_status(ctx, s)) break;
      if (s.at(reg::kStatus) & reg::kError) {
        std::printf("%6u error %u latched: RESET\n", job, s.at(reg::kErrorCode));
        modbus_write_register(ctx, reg::kCommand, 2);
        std::this_thread::sleep_for(20ms);
        continue;
      }
      if (!(s.at(reg::kStatus) & reg::kReady)) {
        std::this_thread::sleep_for(10ms);
        continue;
      }
      const std::uint16_t cmd[4] = {1, job, static_cast<std::uint16_t>(recipe), static_cast<std::uint16_t>(mode)};
      if (modbus_write_registers(ctx, reg::kCommand, 4, cmd) == 4)
        triggered = true;
      else
        std::this_thread::sleep_for(10ms);  // 0x06 busy: retry
    }
    // 4. poll until JOB_ID_ECHO = job.
    bool done = false;
    while (triggered && !expired()) {
      if (read_status(ctx, s) && s.at(reg::kJobIdEcho) == job) {
        done = true;
        break;
      }
      std::this_thread::sleep_for(5ms);
    }
    if (!done) {
      std::printf("%6u timed out after %d ms\n", job, timeout_ms);
      ++failures;
      continue;
    }
    if (s.at(reg::kStatus) & reg::kError) {
      std::printf("%6u %6u error %u\n", job, s.at(reg::kRecipeEcho), s.at(reg::kErrorCode));
      ++failures;
      continue;
    }
    if (s.at(reg::kStatus) & reg::kPickValid)
      std::printf("%6u %6u %9.2f %9.2f %9.2f %8.2f %8.2f %8.2f %6.3f %8u %u found\n", job, s.at(reg::kRecipeEcho),
                  s.f(reg::kPickX, order), s.f(reg::kPickY, order), s.f(reg::kPickZ, order), s.f(reg::kPickRx, order),
                  s.f(reg::kPickRy, order), s.f(reg::kPickRz, order), s.f(reg::kScore, order), s.at(reg::kCycleTimeMs),
                  s.at(reg::kObjectsRemaining));
    else
      std::printf("%6u %6u %9s %9s %9s %8s %8s %8s %6s %8u %u found, no pick\n", job, s.at(reg::kRecipeEcho), "-", "-",
                  "-", "-", "-", "-", "-", s.at(reg::kCycleTimeMs), s.at(reg::kObjectsRemaining));
    std::fflush(stdout);
  }
  modbus_close(ctx);
  return failures ? 1 : 0;
}
