// The Modbus/TCP server on real loopback sockets, driven by a real libmodbus client and by
// hand-made frames for the malformed cases.
#include "motion/modbus_server.hpp"
#include "modbus_test_util.hpp"
#include "motion/register_map.hpp"
#include "sim_daemon.hpp"

#include <gtest/gtest.h>
#include <modbus/modbus.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <thread>

using namespace mfcd::motion;
using namespace std::chrono_literals;
using test::LibmodbusClient;
using test::make_adu;
using test::pick_for_job;
using test::RawClient;
using test::reg_float;
using test::SimulatedDaemon;
using test::wait_for_echo;

namespace {

// A short frame timeout, so that the tests of cut frames do not wait long.
ModbusServerConfig loopback_config(WordOrder order = WordOrder::ABCD) {
  ModbusServerConfig c = test::loopback_config(order);
  c.frame_timeout = 300ms;
  return c;
}

}  // namespace

TEST(ModbusServer, WholeMapInOneRead) {
  ModbusServer server(loopback_config());
  server.start();
  ASSERT_NE(server.port(), 0);
  LibmodbusClient plc(server.port());
  const auto block = plc.read(0, reg::kBlockSize);
  EXPECT_EQ(block[reg::kMapVersionReg], reg::kMapVersion);
  EXPECT_EQ(block[reg::kWordOrder], 0);
  EXPECT_EQ(block[reg::kTestVector], 0x47F1);
  EXPECT_EQ(block[reg::kTestVector + 1], 0x2000);
  EXPECT_EQ(block[reg::kStatus] & reg::kReady, 0) << "no daemon report yet: not ready";
  // Input registers (FC 0x04) mirror the same map.
  std::vector<std::uint16_t> input(reg::kBlockSize);
  ASSERT_EQ(modbus_read_input_registers(plc.ctx, 0, reg::kBlockSize, input.data()), reg::kBlockSize);
  EXPECT_EQ(input[reg::kTestVector], 0x47F1);
}

TEST(ModbusServer, HeartbeatCountsSeconds) {
  ModbusServer server(loopback_config());
  server.start();
  LibmodbusClient plc(server.port());
  const std::uint16_t first = plc.read(reg::kHeartbeat, 1)[0];
  std::this_thread::sleep_for(2500ms);
  const std::uint16_t second = plc.read(reg::kHeartbeat, 1)[0];
  const int delta = static_cast<std::uint16_t>(second - first);
  EXPECT_GE(delta, 2);
  EXPECT_LE(delta, 3);
}

TEST(ModbusServer, JobIdHandshake) {
  ModbusServer server(loopback_config());
  server.start();
  SimulatedDaemon daemon(server, 100ms);
  LibmodbusClient plc(server.port());

  auto block = plc.read(0, reg::kBlockSize);
  ASSERT_TRUE(block[reg::kStatus] & reg::kReady);
  // One FC 0x10 write: command TRIGGER, job 17, recipe 5, mode 0.
  ASSERT_EQ(plc.write(reg::kCommand, {1, 17, 5, 0}), 0);
  block = plc.read(0, reg::kBlockSize);
  EXPECT_EQ(block[reg::kCommand], 0) << "command reads back 0 once taken";
  EXPECT_NE(block[reg::kJobIdEcho], 17) << "result cannot be there before the 100 ms cycle";
  EXPECT_TRUE(block[reg::kStatus] & reg::kBusy);
  EXPECT_FALSE(block[reg::kStatus] & reg::kReady);
  EXPECT_FALSE(block[reg::kStatus] & reg::kDone);

  block = wait_for_echo(plc, 17);
  EXPECT_TRUE(block[reg::kStatus] & reg::kDone);
  EXPECT_TRUE(block[reg::kStatus] & reg::kReady);
  EXPECT_TRUE(block[reg::kStatus] & reg::kPickValid);
  EXPECT_FALSE(block[reg::kStatus] & reg::kBusy);
  EXPECT_EQ(block[reg::kRecipeEcho], 5);
  EXPECT_EQ(block[reg::kObjectsRemaining], 7);
  EXPECT_EQ(block[reg::kCycleTimeMs], 100);
  EXPECT_EQ(block[reg::kCandidateIndex], 2);
  EXPECT_EQ(block[reg::kCandidateCount], 5);
  const PickPose want = pick_for_job(17);
  EXPECT_EQ(reg_float(block, reg::kPickX, WordOrder::ABCD), want.x_mm);
  EXPECT_EQ(reg_float(block, reg::kPickY, WordOrder::ABCD), want.y_mm);
  EXPECT_EQ(reg_float(block, reg::kPickZ, WordOrder::ABCD), want.z_mm);
  EXPECT_EQ(reg_float(block, reg::kPickRx, WordOrder::ABCD), want.rx_deg);
  EXPECT_EQ(reg_float(block, reg::kPickRy, WordOrder::ABCD), want.ry_deg);
  EXPECT_EQ(reg_float(block, reg::kPickRz, WordOrder::ABCD), want.rz_deg);
  EXPECT_EQ(reg_float(block, reg::kScore, WordOrder::ABCD), 0.875f);

  // The same job id again is refused (the echo could not tell the two results apart).
  EXPECT_EQ(plc.write(reg::kCommand, {1, 17, 5, 0}), EMBXILVAL);
  EXPECT_EQ(plc.read(reg::kLastCommandResult, 1)[0], 3);
  // Next job with FC 0x06 writes: parameters first, then the command word alone.
  ASSERT_EQ(modbus_write_register(plc.ctx, reg::kJobId, 18), 1);
  ASSERT_EQ(modbus_write_register(plc.ctx, reg::kMode, 1), 1);
  ASSERT_EQ(modbus_write_register(plc.ctx, reg::kCommand, 1), 1);
  block = wait_for_echo(plc, 18);
  EXPECT_EQ(daemon.last_mode.load(), 1);
  EXPECT_FALSE(block[reg::kStatus] & reg::kPickValid) << "count-only cycle has no pick";
  EXPECT_EQ(reg_float(block, reg::kPickX, WordOrder::ABCD), 0.0f);
  EXPECT_EQ(daemon.triggers.load(), 2);
  EXPECT_EQ(server.stats().commands_queued, 2u);
}

TEST(ModbusServer, TriggerRefusedWhileBusyAndBadCommandsRefused) {
  ModbusServer server(loopback_config());
  server.start();
  SimulatedDaemon daemon(server, 300ms);
  LibmodbusClient plc(server.port());

  ASSERT_EQ(plc.write(reg::kCommand, {1, 40, 1, 0}), 0);
  EXPECT_EQ(plc.write(reg::kCommand, {1, 41, 1, 0}), EMBXSBUSY) << "job 40 still running";
  EXPECT_EQ(plc.read(reg::kLastCommandResult, 1)[0], 6);
  EXPECT_EQ(plc.read(reg::kJobId, 1)[0], 40) << "a refused write changes nothing";
  wait_for_echo(plc, 40);
  EXPECT_EQ(plc.write(reg::kCommand, {1, 0, 1, 0}), EMBXILVAL) << "job id 0";
  EXPECT_EQ(plc.write(reg::kCommand, {1, 42, 1, 9}), EMBXILVAL) << "mode 9";
  EXPECT_EQ(plc.write(reg::kCommand, {77}), EMBXILVAL) << "unknown command";
  EXPECT_EQ(plc.write(reg::kStatus, {1}), EMBXILADD) << "status is read-only";
  EXPECT_EQ(plc.write(6, {1}), EMBXILADD) << "reserved";
  EXPECT_EQ(daemon.triggers.load(), 1);
}

TEST(ModbusServer, ErrorAndReset) {
  ModbusServer server(loopback_config());
  server.start();
  SimulatedDaemon daemon(server, 20ms);
  LibmodbusClient plc(server.port());

  daemon.fail_next = true;
  ASSERT_EQ(plc.write(reg::kCommand, {1, 7, 1, 0}), 0);
  auto block = wait_for_echo(plc, 7);
  EXPECT_TRUE(block[reg::kStatus] & reg::kError);
  EXPECT_FALSE(block[reg::kStatus] & reg::kReady);
  EXPECT_FALSE(block[reg::kStatus] & reg::kPickValid);
  EXPECT_EQ(block[reg::kErrorCode], 301);
  EXPECT_EQ(plc.write(reg::kCommand, {1, 8, 1, 0}), EMBXSBUSY) << "error latched until RESET";
  ASSERT_EQ(plc.write(reg::kCommand, {2}), 0);
  for (int i = 0; i < 100 && (plc.read(reg::kStatus, 1)[0] & reg::kError); ++i) std::this_thread::sleep_for(10ms);
  block = plc.read(0, reg::kBlockSize);
  EXPECT_EQ(block[reg::kErrorCode], 0);
  EXPECT_TRUE(block[reg::kStatus] & reg::kReady);
  EXPECT_EQ(daemon.resets.load(), 1);
  ASSERT_EQ(plc.write(reg::kCommand, {1, 8, 1, 0}), 0);
  wait_for_echo(plc, 8);
}

TEST(ModbusServer, WordOrderCDAB) {
  ModbusServer server(loopback_config(WordOrder::CDAB));
  server.start();
  SimulatedDaemon daemon(server, 10ms);
  LibmodbusClient plc(server.port());
  ASSERT_EQ(plc.write(reg::kCommand, {1, 3, 1, 0}), 0);
  const auto block = wait_for_echo(plc, 3);
  EXPECT_EQ(block[reg::kWordOrder], 1);
  EXPECT_EQ(block[reg::kTestVector], 0x2000);
  EXPECT_EQ(block[reg::kTestVector + 1], 0x47F1);
  EXPECT_EQ(reg_float(block, reg::kPickX, WordOrder::CDAB), pick_for_job(3).x_mm);
  EXPECT_NE(reg_float(block, reg::kPickX, WordOrder::ABCD), pick_for_job(3).x_mm);
}

TEST(ModbusServer, ReadWriteMultipleRegisters) {
  ModbusServer server(loopback_config());
  server.start();
  SimulatedDaemon daemon(server, 10ms);
  LibmodbusClient plc(server.port());
  // FC 0x17: set job/recipe/mode (no command) and read the status block in one exchange.
  const std::uint16_t params[3] = {90, 4, 0};
  std::uint16_t status[28];
  ASSERT_EQ(modbus_write_and_read_registers(plc.ctx, reg::kJobId, 3, params, reg::kStatus, 28, status), 28);
  EXPECT_EQ(status[reg::kTestVector - reg::kStatus], 0x47F1);
  EXPECT_EQ(plc.read(reg::kJobId, 3), (std::vector<std::uint16_t>{90, 4, 0}));
  EXPECT_EQ(daemon.triggers.load(), 0);
}

TEST(ModbusServer, AnyUnitIdIsAnswered) {
  ModbusServer server(loopback_config());
  server.start();
  RawClient raw(server.port());
  for (std::uint8_t unit : {0x00, 0x01, 0xff}) {
    raw.send(make_adu(0x0101, {0x03, 0, reg::kTestVector, 0, 2}, unit));
    const auto rsp = raw.receive(13);
    ASSERT_TRUE(rsp);
    ASSERT_EQ(rsp->size(), 13u);
    EXPECT_EQ((*rsp)[6], unit);
    EXPECT_EQ((*rsp)[7], 0x03);
    EXPECT_EQ((*rsp)[9], 0x47);
    EXPECT_EQ((*rsp)[10], 0xF1);
  }
}

TEST(ModbusServer, SeveralClientsAtOnce) {
  ModbusServer server(loopback_config());
  server.start();
  SimulatedDaemon daemon(server, 5ms);
  std::atomic<int> failures{0};
  std::vector<std::thread> readers;
  for (int t = 0; t < 4; ++t)
    readers.emplace_back([&] {
      LibmodbusClient client(server.port());
      for (int i = 0; i < 200; ++i) {
        const auto block = client.read(0, reg::kBlockSize);
        if (block[reg::kTestVector] != 0x47F1 || block[reg::kMapVersionReg] != reg::kMapVersion) ++failures;
        // A reader sees either no pick or the pick of exactly the echoed job.
        if ((block[reg::kStatus] & reg::kPickValid) &&
            reg_float(block, reg::kPickX, WordOrder::ABCD) != pick_for_job(block[reg::kJobIdEcho]).x_mm)
          ++failures;
      }
    });
  {
    LibmodbusClient plc(server.port());
    for (std::uint16_t job = 1; job <= 20; ++job) {
      ASSERT_EQ(plc.write(reg::kCommand, {1, job, 1, 0}), 0);
      wait_for_echo(plc, job);
    }
  }
  for (auto& t : readers) t.join();
  EXPECT_EQ(failures.load(), 0);
  EXPECT_EQ(daemon.triggers.load(), 20);
  EXPECT_GE(server.stats().connections_accepted, 5u);
}

TEST(ModbusServer, ClientDroppingMidFrameDoesNotDisturbOthers) {
  ModbusServer server(loopback_config());
  server.start();
  LibmodbusClient plc(server.port());
  {
    RawClient dropper(server.port());
    auto frame = make_adu(1, {0x10, 0, 0, 0, 4, 8, 0, 1, 0, 9, 0, 1, 0, 0});
    frame.resize(9);  // half a request, then gone
    dropper.send(frame);
    std::this_thread::sleep_for(50ms);
  }
  EXPECT_EQ(plc.read(reg::kTestVector, 2)[0], 0x47F1);
  for (int i = 0; i < 100 && server.stats().connections_dropped < 1; ++i) std::this_thread::sleep_for(10ms);
  EXPECT_EQ(server.stats().connections_dropped, 1u);
  EXPECT_EQ(plc.read(reg::kJobId, 1)[0], 0) << "the half write must not land";

  // A client that stalls mid-frame is closed after frame_timeout (300 ms here).
  RawClient staller(server.port());
  staller.send({0x00, 0x01, 0x00});
  EXPECT_TRUE(staller.closed_by_server(2000));
  EXPECT_EQ(plc.read(reg::kTestVector, 2)[1], 0x2000);
}

TEST(ModbusServer, MalformedFramesGetExceptionsOrClose) {
  ModbusServer server(loopback_config());
  server.start();
  LibmodbusClient bystander(server.port());

  struct Case {
    const char* what;
    std::vector<std::uint8_t> pdu;
    std::uint8_t exception;
  };
  const Case cases[] = {
      {"unknown function 0x2b", {0x2b, 0x0e, 0x01, 0x00}, 0x01},
      {"read coils (no coils in the map)", {0x01, 0, 0, 0, 1}, 0x01},
      {"read past the map", {0x03, 0, 90, 0, 10}, 0x02},
      {"read quantity 0", {0x03, 0, 0, 0, 0}, 0x03},
      {"read quantity 126", {0x03, 0, 0, 0, 126}, 0x03},
      {"write to the status block", {0x06, 0, reg::kStatus, 0, 1}, 0x02},
      {"FC 0x10 byte count disagrees with quantity", {0x10, 0, 0, 0, 2, 2, 0, 1}, 0x03},
      {"FC 0x17 write quantity 121 with 2 data bytes", {0x17, 0, 0, 0, 1, 0, 0, 0, 0x79, 2, 0, 0}, 0x03},
      {"FC 0x17 byte count without data", {0x17, 0, 0, 0, 1, 0, 0, 0, 1, 2}, 0x03},
      {"FC 0x17 write outside the map", {0x17, 0, 0, 0, 1, 0xff, 0xf0, 0, 1, 2, 0, 0}, 0x02},
      {"read with short PDU", {0x03, 0, 0}, 0x03},
  };
  RawClient raw(server.port());
  std::uint16_t tid = 0x0100;
  for (const Case& c : cases) {
    raw.send(make_adu(++tid, c.pdu, 0x11));
    const auto rsp = raw.receive(9);
    ASSERT_TRUE(rsp) << c.what << ": server closed the connection";
    ASSERT_EQ(rsp->size(), 9u) << c.what;
    EXPECT_EQ((*rsp)[0], tid >> 8) << c.what;
    EXPECT_EQ((*rsp)[1], tid & 0xff) << c.what;
    EXPECT_EQ((*rsp)[5], 3) << c.what;
    EXPECT_EQ((*rsp)[6], 0x11) << c.what;
    EXPECT_EQ((*rsp)[7], c.pdu[0] | 0x80) << c.what;
    EXPECT_EQ((*rsp)[8], c.exception) << c.what;
  }
  // The same connection still serves a good request afterwards.
  raw.send(make_adu(7, {0x03, 0, reg::kTestVector, 0, 1}));
  const auto ok = raw.receive(11);
  ASSERT_TRUE(ok);
  ASSERT_EQ(ok->size(), 11u);
  EXPECT_EQ((*ok)[9], 0x47);

  // Headers that leave no trustworthy frame boundary close the connection.
  const std::vector<std::vector<std::uint8_t>> fatal = {
      {0, 1, 0, 0, 0, 1, 0xff},                 // MBAP length 1: no function code
      {0, 1, 0, 0, 0, 0, 0xff},                 // MBAP length 0
      {0, 1, 0, 7, 0, 6, 0xff, 3, 0, 0, 0, 1},  // protocol id 7
      {0, 1, 0, 0, 0x01, 0x00, 0xff, 3},        // MBAP length 256 > 254
  };
  for (const auto& frame : fatal) {
    RawClient bad(server.port());
    bad.send(frame);
    EXPECT_TRUE(bad.closed_by_server());
  }
  EXPECT_EQ(server.stats().connections_dropped, fatal.size());
  EXPECT_EQ(bystander.read(reg::kTestVector, 2)[0], 0x47F1);
  EXPECT_GE(server.stats().exceptions_sent, std::size(cases));
}

TEST(ModbusServer, PipelinedRequestsInOneSegment) {
  ModbusServer server(loopback_config());
  server.start();
  RawClient raw(server.port());
  std::vector<std::uint8_t> both = make_adu(1, {0x03, 0, reg::kTestVector, 0, 1});
  const auto second = make_adu(2, {0x03, 0, reg::kTestVector + 1, 0, 1});
  both.insert(both.end(), second.begin(), second.end());
  raw.send(both);
  const auto rsp = raw.receive(22);
  ASSERT_TRUE(rsp);
  ASSERT_EQ(rsp->size(), 22u);
  EXPECT_EQ((*rsp)[1], 1);
  EXPECT_EQ((*rsp)[9], 0x47);
  EXPECT_EQ((*rsp)[12], 2);
  EXPECT_EQ((*rsp)[20], 0x20);
}

TEST(ModbusServer, AllowListRefusesOthers) {
  ModbusServerConfig config = loopback_config();
  config.allow_list = {"127.0.0.2", "10.0.0.0/8"};
  ModbusServer server(config);
  server.start();
  RawClient refused(server.port(), "127.0.0.1");
  EXPECT_TRUE(refused.closed_by_server());
  RawClient allowed(server.port(), "127.0.0.2");
  allowed.send(make_adu(5, {0x03, 0, reg::kTestVector, 0, 2}));
  const auto rsp = allowed.receive(13);
  ASSERT_TRUE(rsp);
  EXPECT_EQ(rsp->size(), 13u);
  EXPECT_EQ(server.stats().connections_refused, 1u);
}

TEST(ModbusServer, MaxClientsEvictsTheLongestIdleClient) {
  ModbusServerConfig config = loopback_config();
  config.max_clients = 2;
  ModbusServer server(config);
  server.start();
  RawClient a(server.port()), b(server.port());
  a.send(make_adu(1, {0x03, 0, reg::kTestVector, 0, 1}));
  ASSERT_TRUE(a.receive(11));
  std::this_thread::sleep_for(50ms);
  b.send(make_adu(2, {0x03, 0, reg::kTestVector, 0, 1}));
  ASSERT_TRUE(b.receive(11));
  // A third connection (a PLC back from a power cycle, say) takes the slot of a, idle longest.
  LibmodbusClient third(server.port());
  EXPECT_EQ(third.read(reg::kTestVector, 1)[0], 0x47F1);
  EXPECT_TRUE(a.closed_by_server());
  b.send(make_adu(3, {0x03, 0, reg::kTestVector, 0, 1}));
  const auto rsp = b.receive(11);
  ASSERT_TRUE(rsp);
  EXPECT_EQ(rsp->size(), 11u) << "b kept its connection";
  const ModbusServerStats s = server.stats();
  EXPECT_EQ(s.connections_evicted, 1u);
  EXPECT_EQ(s.connections_refused, 0u);
  EXPECT_EQ(s.clients_now, 2u);
}

TEST(ModbusServer, MaxClientsRefusesWhenEveryClientIsMidFrame) {
  ModbusServerConfig config = loopback_config();
  config.max_clients = 1;
  config.frame_timeout = 2000ms;
  ModbusServer server(config);
  server.start();
  RawClient a(server.port());
  const std::vector<std::uint8_t> frame = make_adu(1, {0x03, 0, reg::kTestVector, 0, 1});
  a.send({frame.begin(), frame.begin() + 4});
  std::this_thread::sleep_for(100ms);  // the server has taken a's first bytes
  RawClient other(server.port());
  EXPECT_TRUE(other.closed_by_server()) << "a is mid-frame: not evicted, the newcomer is refused";
  a.send({frame.begin() + 4, frame.end()});
  const auto rsp = a.receive(11);
  ASSERT_TRUE(rsp);
  EXPECT_EQ(rsp->size(), 11u);
  EXPECT_EQ(server.stats().connections_refused, 1u);
  EXPECT_EQ(server.stats().connections_evicted, 0u);
}

TEST(ModbusServer, BadConfigurationIsNamed) {
  ModbusServerConfig config = loopback_config();
  config.bind_address = "127.0.0.300";
  EXPECT_NE(config.validate().find("bind_address '127.0.0.300'"), std::string::npos);
  config = loopback_config();
  config.allow_list = {"10.0.0.0/33"};
  EXPECT_NE(config.validate().find("allow_list entry '10.0.0.0/33'"), std::string::npos);
  EXPECT_THROW(ModbusServer{config}, std::invalid_argument);
  config = loopback_config();
  config.max_clients = 0;
  EXPECT_NE(config.validate().find("max_clients"), std::string::npos);
  config = loopback_config();
  config.idle_timeout = 50ms;
  EXPECT_NE(config.validate().find("idle_timeout_ms 50"), std::string::npos);
}

TEST(ModbusServer, PortInUseIsNamed) {
  ModbusServer first(loopback_config());
  first.start();
  ModbusServerConfig config = loopback_config();
  config.port = first.port();
  ModbusServer second(config);
  try {
    second.start();
    FAIL() << "second bind to the same port succeeded";
  } catch (const std::system_error& e) {
    EXPECT_NE(std::string(e.what()).find("127.0.0.1:" + std::to_string(first.port())), std::string::npos) << e.what();
    EXPECT_EQ(e.code().value(), EADDRINUSE);
  }
}

TEST(ModbusServer, CommandFdWakesTheDaemon) {
  ModbusServer server(loopback_config());
  server.start();
  RobotReport ready;
  ready.ready = 1;
  server.publish(ready);
  pollfd p{server.command_fd(), POLLIN, 0};
  EXPECT_EQ(::poll(&p, 1, 0), 0);
  LibmodbusClient plc(server.port());
  ASSERT_EQ(plc.write(reg::kCommand, {1, 5, 9, 0}), 0);
  ASSERT_EQ(::poll(&p, 1, 2000), 1);
  const auto cmd = server.next_command();
  ASSERT_TRUE(cmd);
  EXPECT_EQ(cmd->kind, PlcCommand::Kind::Trigger);
  EXPECT_EQ(cmd->job_id, 5);
  EXPECT_EQ(cmd->recipe_id, 9);
  EXPECT_FALSE(server.next_command());
  EXPECT_EQ(::poll(&p, 1, 0), 0) << "drained eventfd";
}

// docs/register-map.md, "Worked example": the same requests, the same register values.
TEST(ModbusServer, WorkedExampleFromTheRegisterMapDoc) {
  ModbusServer server(loopback_config());
  server.start();
  SimulatedDaemon daemon(server, 200ms);
  LibmodbusClient plc(server.port());
  ASSERT_EQ(plc.write(reg::kCommand, {1, 20, 3, 0}), 0);
  auto regs = wait_for_echo(plc, 20);
  EXPECT_EQ(regs[reg::kStatus], 0x0035);

  // The trigger exactly as the doc shows it on the wire.
  RawClient raw(server.port());
  raw.send({0x00, 0x01, 0x00, 0x00, 0x00, 0x0F, 0xFF, 0x10, 0x00, 0x00, 0x00,
            0x04, 0x08, 0x00, 0x01, 0x00, 0x15, 0x00, 0x03, 0x00, 0x00});
  const auto rsp = raw.receive(12);
  ASSERT_TRUE(rsp);
  EXPECT_EQ(*rsp, (std::vector<std::uint8_t>{0x00, 0x01, 0x00, 0x00, 0x00, 0x06, 0xFF, 0x10, 0x00, 0x00, 0x00, 0x04}));

  regs = plc.read(0, reg::kBlockSize);
  EXPECT_EQ((std::vector<std::uint16_t>(regs.begin(), regs.begin() + 4)), (std::vector<std::uint16_t>{0, 21, 3, 0}));
  EXPECT_EQ(regs[reg::kStatus], 0x0032);
  EXPECT_EQ(regs[reg::kJobIdEcho], 20);

  regs = wait_for_echo(plc, 21);
  EXPECT_EQ(regs[reg::kStatus], 0x0035);
  EXPECT_EQ(regs[reg::kErrorCode], 0);
  EXPECT_EQ(regs[reg::kRecipeEcho], 3);
  const std::vector<std::uint16_t> pick(regs.begin() + reg::kPickX, regs.begin() + reg::kScore + 2);
  EXPECT_EQ(pick, (std::vector<std::uint16_t>{0x42F2, 0x0000, 0xC37A, 0x8000, 0x4229, 0x0000, 0x4334, 0x0000, 0xBF00,
                                              0x0000, 0xC28A, 0x0000, 0x3F60, 0x0000}));
}

namespace {

std::vector<std::uint16_t> pose_block(const float v[6], std::uint16_t valid, std::uint16_t seq, WordOrder order) {
  std::vector<std::uint16_t> block;
  for (int i = 0; i < 6; ++i) {
    const auto w = encode_float(v[i], order);
    block.push_back(w[0]);
    block.push_back(w[1]);
  }
  block.push_back(valid);
  block.push_back(seq);
  return block;
}

RobotPoseReading wait_for_pose_writes(const ModbusServer& server, std::uint32_t writes) {
  // The write is answered after the server publishes the pose, so it is there at once.
  const RobotPoseReading p = server.robot_pose();
  EXPECT_EQ(p.writes, writes);
  return p;
}

}  // namespace

// Map version 2: the PLC writes the robot flange pose (FC 0x10) for calibration views.
TEST(ModbusServer, RobotPoseBlockWrittenByThePlc) {
  for (const WordOrder order : {WordOrder::ABCD, WordOrder::CDAB}) {
    ModbusServer server(loopback_config(order));
    server.start();
    LibmodbusClient plc(server.port());
    EXPECT_EQ(plc.read(reg::kMapVersionReg, 1)[0], reg::kMapVersion);
    EXPECT_EQ(server.robot_pose().writes, 0u) << "never written";

    const float pose[6] = {512.25f, -130.5f, 740.125f, 179.5f, -2.25f, 45.0f};
    ASSERT_EQ(plc.write(reg::kRobotPoseX, pose_block(pose, 1, 17, order)), 0);
    RobotPoseReading p = wait_for_pose_writes(server, 1);
    EXPECT_EQ(p.valid, 1);
    EXPECT_EQ(p.sequence, 17);
    EXPECT_EQ(p.x_mm, pose[0]);
    EXPECT_EQ(p.y_mm, pose[1]);
    EXPECT_EQ(p.z_mm, pose[2]);
    EXPECT_EQ(p.rx_deg, pose[3]);
    EXPECT_EQ(p.ry_deg, pose[4]);
    EXPECT_EQ(p.rz_deg, pose[5]);
    // The block reads back as written (the PLC can verify its write).
    EXPECT_EQ(plc.read(reg::kRobotPoseX, 14), pose_block(pose, 1, 17, order));
    if (order == WordOrder::ABCD) {  // the example in docs/register-map.md, word for word
      EXPECT_EQ(plc.read(reg::kRobotPoseX, 14),
                (std::vector<std::uint16_t>{0x4400, 0x1000, 0xC302, 0x8000, 0x4439, 0x0800, 0x4333, 0x8000, 0xC010,
                                            0x0000, 0x4234, 0x0000, 1, 17}));
    }

    // Clearing the valid flag alone (FC 0x06) keeps the pose and marks it not current.
    ASSERT_EQ(modbus_write_register(plc.ctx, reg::kRobotPoseValid, 0), 1);
    p = wait_for_pose_writes(server, 2);
    EXPECT_EQ(p.valid, 0);
    EXPECT_EQ(p.x_mm, pose[0]);

    // Bad writes get exceptions and change nothing.
    const float nan_pose[6] = {std::nanf(""), 0, 0, 0, 0, 0};
    EXPECT_EQ(plc.write(reg::kRobotPoseX, pose_block(nan_pose, 1, 18, order)), EMBXILVAL) << "NaN";
    const float inf_pose[6] = {0, 0, 0, 0, 0, INFINITY};
    EXPECT_EQ(plc.write(reg::kRobotPoseX, pose_block(inf_pose, 1, 18, order)), EMBXILVAL) << "infinity";
    EXPECT_EQ(plc.write(reg::kRobotPoseValid, {2}), EMBXILVAL) << "valid flag must be 0 or 1";
    EXPECT_EQ(plc.write(reg::kRobotPoseX - 2, {0, 0, 0, 0}), EMBXILADD) << "starts in TEST_VECTOR (read-only)";
    EXPECT_EQ(plc.write(reg::kRobotPoseSeq, {1, 2}), EMBXILADD) << "runs into the read-only 50";
    EXPECT_EQ(plc.write(reg::kMode, std::vector<std::uint16_t>(reg::kRobotPoseSeq - reg::kMode + 1, 0)), EMBXILADD)
        << "control and pose blocks in one write cross the read-only status block";
    EXPECT_EQ(plc.write(reg::kLookReason, {1}), EMBXILADD) << "read-only";
    EXPECT_EQ(server.robot_pose().writes, 2u);
    EXPECT_EQ(plc.read(reg::kRobotPoseX, 14), pose_block(pose, 0, 17, order));
    // The pose block is not a command: nothing was queued for the daemon.
    EXPECT_FALSE(server.next_command().has_value());
  }
}
