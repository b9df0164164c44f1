// Liveness of the Modbus/TCP server, both ways: peers that go silent or vanish lose their
// slot (idle timeout, TCP keepalive), and the server's own signs of life (HEARTBEAT,
// serving(), drain()) say what the daemon behind it is doing. Real loopback sockets.
#include "modbus_test_util.hpp"
#include "motion/modbus_server.hpp"
#include "motion/register_map.hpp"

#include <gtest/gtest.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/resource.h>
#include <sys/socket.h>

#include <chrono>
#include <thread>

using namespace mfcd::motion;
using mfcd::UniqueFd;
using namespace std::chrono_literals;
using test::make_adu;
using test::RawClient;

namespace {

ModbusServerConfig loopback_config() {
  ModbusServerConfig c;
  c.bind_address = "127.0.0.1";
  c.port = 0;
  c.frame_timeout = 300ms;
  return c;
}

std::uint16_t read_heartbeat(RawClient& plc) {
  static std::uint16_t transaction = 0;
  plc.send(make_adu(++transaction, {0x03, 0, reg::kHeartbeat, 0, 1}));
  const auto rsp = plc.receive(11);
  if (!rsp || rsp->size() != 11) throw std::runtime_error("no answer to a heartbeat read");
  return static_cast<std::uint16_t>(((*rsp)[9] << 8) | (*rsp)[10]);
}

int int_option(int fd, int level, int name) {
  int value = -1;
  socklen_t len = sizeof(value);
  if (::getsockopt(fd, level, name, &value, &len) != 0) return -1;
  return value;
}

}  // namespace

TEST(ModbusLiveness, SilentClientIsClosedAfterTheIdleTimeout) {
  ModbusServerConfig config = loopback_config();
  config.idle_timeout = 400ms;
  ModbusServer server(config);
  server.start();
  RawClient silent(server.port());
  RawClient polling(server.port());
  const auto start = std::chrono::steady_clock::now();
  // The polling client asks every 100 ms for 1 s: it keeps its connection throughout.
  while (std::chrono::steady_clock::now() - start < 1000ms) {
    polling.send(make_adu(1, {0x03, 0, reg::kTestVector, 0, 1}));
    const auto rsp = polling.receive(11);
    ASSERT_TRUE(rsp && rsp->size() == 11u) << "an active client must never be closed as idle";
    std::this_thread::sleep_for(100ms);
  }
  EXPECT_TRUE(silent.closed_by_server(100)) << "closed by the time the polling client finished";
  EXPECT_EQ(server.stats().connections_idle, 1u);
  EXPECT_EQ(server.stats().clients_now, 1u);
}

TEST(ModbusLiveness, AcceptedSocketsCarryKeepaliveAndUserTimeout) {
  // The options are set on the server's side of the connection; they are read back here from
  // a loopback connection's accepted end, the way the server's accept loop sets them.
  UniqueFd listener(::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0));
  ASSERT_TRUE(listener);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::bind(listener.get(), reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
  ASSERT_EQ(::listen(listener.get(), 1), 0);
  socklen_t len = sizeof(addr);
  ::getsockname(listener.get(), reinterpret_cast<sockaddr*>(&addr), &len);
  RawClient client(ntohs(addr.sin_port));
  UniqueFd accepted(::accept4(listener.get(), nullptr, nullptr, SOCK_CLOEXEC));
  ASSERT_TRUE(accepted);
  EXPECT_EQ(int_option(accepted.get(), SOL_SOCKET, SO_KEEPALIVE), 0) << "the kernel default, before";
  apply_client_socket_options(accepted.get());
  EXPECT_EQ(int_option(accepted.get(), SOL_SOCKET, SO_KEEPALIVE), 1);
  EXPECT_EQ(int_option(accepted.get(), IPPROTO_TCP, TCP_KEEPIDLE), kKeepaliveIdle.count());
  EXPECT_EQ(int_option(accepted.get(), IPPROTO_TCP, TCP_KEEPINTVL), kKeepaliveInterval.count());
  EXPECT_EQ(int_option(accepted.get(), IPPROTO_TCP, TCP_KEEPCNT), kKeepaliveProbes);
  EXPECT_EQ(int_option(accepted.get(), IPPROTO_TCP, TCP_USER_TIMEOUT), kUnacknowledgedTimeout.count());
  EXPECT_EQ(int_option(accepted.get(), IPPROTO_TCP, TCP_NODELAY), 1);
  // A dead peer is found well within the idle timeout's default.
  EXPECT_LT(kKeepaliveIdle + kKeepaliveProbes * kKeepaliveInterval, ModbusServerConfig{}.idle_timeout);
}

TEST(ModbusLiveness, HeartbeatFreezesWhenTheHealthLeaseLapses) {
  ModbusServer server(loopback_config());
  server.start();
  RawClient plc(server.port());
  // Healthy for the next 1.2 s only: at most the beat at ~1 s counts.
  server.lease_health(std::chrono::steady_clock::now() + 1200ms);
  const std::uint16_t h0 = read_heartbeat(plc);
  std::this_thread::sleep_for(2500ms);
  const std::uint16_t h1 = read_heartbeat(plc);
  EXPECT_LE(static_cast<std::uint16_t>(h1 - h0), 1);
  std::this_thread::sleep_for(1100ms);
  EXPECT_EQ(read_heartbeat(plc), h1) << "frozen while the lease is lapsed";
  // Renewed: it counts again.
  server.lease_health(std::chrono::steady_clock::now() + 10s);
  std::this_thread::sleep_for(2100ms);
  EXPECT_GE(static_cast<std::uint16_t>(read_heartbeat(plc) - h1), 1);
}

TEST(ModbusLiveness, DrainWaitsUntilEveryClientHasReadTheLastReport) {
  ModbusServer server(loopback_config());
  server.start();
  EXPECT_TRUE(server.drain(0ms)) << "nobody connected: nothing to wait for";
  RawClient plc(server.port());
  std::this_thread::sleep_for(50ms);  // accepted
  RobotReport final_report;
  final_report.job_id = 41;
  server.publish(final_report);
  EXPECT_FALSE(server.drain(100ms)) << "the PLC has not read since the publish";
  plc.send(make_adu(1, {0x03, 0, reg::kJobIdEcho, 0, 1}));
  const auto rsp = plc.receive(11);
  ASSERT_TRUE(rsp && rsp->size() == 11u);
  EXPECT_EQ((*rsp)[10], 41) << "the read saw the final report";
  EXPECT_TRUE(server.drain(1000ms));
}

TEST(ModbusLiveness, ServingTurnsFalseWhenTheServerThreadDies) {
#ifdef MFC_UBSAN
  GTEST_SKIP() << "descriptors used up: UBSan's vptr check cannot probe memory (pipe fails) and "
                  "reports a false 'invalid vptr'; the release build runs this test";
#endif
  ModbusServer server(loopback_config());
  server.start();
  RawClient a(server.port()), b(server.port());
  a.send(make_adu(1, {0x03, 0, reg::kTestVector, 0, 1}));
  ASSERT_TRUE(a.receive(11));
  b.send(make_adu(1, {0x03, 0, reg::kTestVector, 0, 1}));
  ASSERT_TRUE(b.receive(11));
  EXPECT_TRUE(server.serving());
  // A real fault: poll() fails with EINVAL once it watches more descriptors than
  // RLIMIT_NOFILE allows (stop event, listener and two clients > 3).
  rlimit saved{};
  ASSERT_EQ(::getrlimit(RLIMIT_NOFILE, &saved), 0);
  rlimit low = saved;
  low.rlim_cur = 3;
  ASSERT_EQ(::setrlimit(RLIMIT_NOFILE, &low), 0);
  const auto end = std::chrono::steady_clock::now() + 3s;
  while (server.serving() && std::chrono::steady_clock::now() < end) std::this_thread::sleep_for(10ms);
  ASSERT_EQ(::setrlimit(RLIMIT_NOFILE, &saved), 0);
  EXPECT_FALSE(server.serving());
  EXPECT_TRUE(server.running()) << "the thread object is still there until stop()";
  server.stop();
  EXPECT_FALSE(server.running());
}
