// The daemon-level fault matrix: a PLC triggers jobs back to back on the rendered simulated cell
// while faults arrive at random phases of the cycle. Below the HAL (fault_source.hpp): camera
// timeouts, driver error buffers, stale frames, an unplugged camera that comes back, an LED line
// that fails to switch. From outside: SIGHUP reloads, invalid UTF-8 and oversized lines on the
// control socket, control-socket cycles competing with the PLC's, Modbus clients that drop
// mid-frame or send garbage. Every accepted job must end, within its budget + 2 s, with
// JOB_ID_ECHO = job and either a result or an ERROR_CODE; the LEDs must be off after every capture;
// the daemon must still serve and stop cleanly.
#include <gtest/gtest.h>

#include <modbus/modbus.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <atomic>
#include <map>
#include <random>
#include <thread>

#include "daemon_fixture.hpp"
#include "daemon_process.hpp"
#include "motion/register_map.hpp"
#include "plc_test_client.hpp"

using namespace mfcd::daemon::test;
using namespace mfcd::motion;

namespace {

constexpr int kBudgetMs = 1000;
constexpr int kJobs = 40;

// Connects to the Modbus port, sends `bytes`, closes.
void send_raw(int port, const std::string& bytes) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0)
    (void)::send(fd, bytes.data(), bytes.size(), MSG_NOSIGNAL);
  ::close(fd);
}

}  // namespace

class DaemonFaultMatrix : public DaemonFixture {};

TEST_F(DaemonFaultMatrix, EveryAcceptedJobEndsWithAResultOrAnErrorCode) {
  start_daemon("fault-matrix", kBudgetMs, {"MFCD_TEST_FAULTS=7,25"});
  if (IsSkipped() || HasFailure()) return;
  DaemonProcess& proc = *this->proc_;
  const fs::path socket = proc.dir() / "ctl.sock";

  std::atomic<bool> done{false};
  std::map<std::string, int> outside;  // fault from outside -> times sent
  std::thread faults([&] {
    std::mt19937 rng(11);
    std::uniform_int_distribution<int> pause(30, 400), kind(0, 5);
    while (!done.load()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(pause(rng)));
      switch (kind(rng)) {
        case 0:
          proc.signal(SIGHUP);
          ++outside["SIGHUP reload"];
          break;
        case 1:
          ctl_line(socket, "\xff\xfe{\"cmd\":\"st\xc3\n", 2000);
          ++outside["invalid UTF-8 control line"];
          break;
        case 2:
          ctl_line(socket, std::string(1 << 20, 'x') + "\n", 2000);
          ++outside["1 MiB control line"];
          break;
        case 3:
          ctl_line(socket, "{\"cmd\":\"trigger\"}\n", 5000);
          ++outside["control-socket cycle"];
          break;
        case 4:
          send_raw(port_, std::string("\x00\x01\x00", 3));
          ++outside["Modbus client gone mid-frame"];
          break;
        default: {
          std::string junk(260, '\0');
          for (char& c : junk) c = static_cast<char>(rng() & 0xff);
          send_raw(port_, junk);
          ++outside["Modbus garbage"];
          break;
        }
      }
    }
  });

  Client plc(port_);
  ASSERT_TRUE(plc.connected);
  std::map<int, int> ended;  // ERROR_CODE -> jobs (0: a result)
  int accepted = 0, picks = 0;
  double slowest_ms = 0;
  for (std::uint16_t job = 1; job <= kJobs; ++job) {
    // Ready, clearing a latched error as a PLC does.
    Regs r;
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    bool ready = false;
    while (!ready && std::chrono::steady_clock::now() < until) {
      if (plc.read(r)) {
        ready = r.at(reg::kStatus) & reg::kReady;
        if (r.at(reg::kStatus) & reg::kError) {
          const std::uint16_t reset = 2;
          modbus_write_registers(plc.ctx, reg::kCommand, 1, &reset);
        }
      }
      if (!ready) std::this_thread::sleep_for(5ms);
    }
    ASSERT_TRUE(ready) << "job " << job << ": never READY\n" << proc.log();
    const auto t0 = std::chrono::steady_clock::now();
    if (plc.trigger(job, 0) != 0) continue;  // refused (busy: a control cycle or a reload): not accepted
    ++accepted;
    ASSERT_TRUE(plc.wait_for(job, r, kBudgetMs + 2000)) << "job " << job << " accepted but not answered\n"
                                                        << proc.log();
    slowest_ms =
        std::max(slowest_ms, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    const std::uint16_t error = r.at(reg::kErrorCode);
    const bool pick = r.at(reg::kStatus) & reg::kPickValid;
    EXPECT_FALSE(pick && error != 0) << "job " << job;
    ++ended[error];
    picks += pick;
  }
  done = true;
  faults.join();

  std::string summary = "accepted " + std::to_string(accepted) + " of " + std::to_string(kJobs) + ", picks " +
                        std::to_string(picks) + ", slowest answer " + std::to_string(slowest_ms) + " ms; ended:";
  for (const auto& [code, n] : ended) summary += " code " + std::to_string(code) + " x" + std::to_string(n);
  summary += "; sent:";
  for (const auto& [what, n] : outside) summary += " " + what + " x" + std::to_string(n);
  std::printf("%s\n", summary.c_str());
  EXPECT_GE(accepted, kJobs / 2) << summary;
  EXPECT_GT(picks, 0) << summary;
  // The injected camera faults reached the PLC as capture errors, and the cell came back each time.
  EXPECT_GT(ended[static_cast<int>(2)], 0) << summary;
  for (const auto& [code, n] : ended)
    EXPECT_TRUE(code == 0 || code == 2 || code == 3) << "unexpected ERROR_CODE " << code << ": " << summary;
  const std::string log = proc.log();
  EXPECT_EQ(log.find("LEDs were not all off"), std::string::npos) << log;
  const json status = proc.ctl({{"cmd", "status"}});
  EXPECT_TRUE(status.contains("modbus")) << status.dump();
  proc.signal(SIGTERM);
  EXPECT_EQ(proc.wait(15000), 0) << proc.log();
}
