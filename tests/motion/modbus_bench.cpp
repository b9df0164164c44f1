// Robot-link costs: Modbus/TCP request round trip on loopback with N concurrent libmodbus
// clients, and the daemon-side publish (seqlock) and request-guard costs.
//   build/mine/bench/motion_modbus_bench --benchmark_out=motion_modbus_bench.json
//       --benchmark_out_format=json      (table on stdout, JSON in the file)
#include "motion/modbus_server.hpp"
#include "motion/register_map.hpp"
#include "motion/request_guard.hpp"

#include <benchmark/benchmark.h>
#include <modbus/modbus.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <stdexcept>
#include <vector>

using namespace mfcd::motion;

namespace {

ModbusServer& shared_server() {
  static ModbusServer* server = [] {
    ModbusServerConfig config;
    config.bind_address = "127.0.0.1";
    config.port = 0;
    config.max_clients = 16;
    auto* s = new ModbusServer(config);
    s->start();
    RobotReport r;
    r.ready = 1;
    r.pick_valid = 1;
    r.job_id = 1;
    s->publish(r);
    return s;
  }();
  return *server;
}

// One FC 0x03 read of the status + pick block (28 registers), what a PLC polls.
void BM_ModbusReadStatusBlock(benchmark::State& state) {
  ModbusServer& server = shared_server();
  modbus_t* ctx = modbus_new_tcp("127.0.0.1", server.port());
  if (!ctx || modbus_connect(ctx) != 0) {
    state.SkipWithError("cannot connect");
    return;
  }
  std::uint16_t regs[28];
  for (auto _ : state) {
    if (modbus_read_registers(ctx, reg::kStatus, 28, regs) != 28) {
      state.SkipWithError("read failed");
      break;
    }
    benchmark::DoNotOptimize(regs);
  }
  state.SetItemsProcessed(state.iterations());
  modbus_close(ctx);
  modbus_free(ctx);
}
BENCHMARK(BM_ModbusReadStatusBlock)->Threads(1)->Threads(4)->Threads(8)->UseRealTime();

// Per-request round-trip latency percentiles (µs) seen by each of N concurrent clients,
// averaged over the clients. ("Time" above is wall time per request across all clients.)
void BM_ModbusRoundTripLatency(benchmark::State& state) {
  ModbusServer& server = shared_server();
  modbus_t* ctx = modbus_new_tcp("127.0.0.1", server.port());
  if (!ctx || modbus_connect(ctx) != 0) {
    state.SkipWithError("cannot connect");
    return;
  }
  std::vector<double> us;
  us.reserve(1 << 20);
  std::uint16_t regs[28];
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    if (modbus_read_registers(ctx, reg::kStatus, 28, regs) != 28) {
      state.SkipWithError("read failed");
      break;
    }
    us.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
  }
  if (!us.empty()) {
    std::sort(us.begin(), us.end());
    const auto pct = [&](double p) { return us[static_cast<std::size_t>(p * static_cast<double>(us.size() - 1))]; };
    state.counters["p50_us"] = benchmark::Counter(pct(0.50), benchmark::Counter::kAvgThreads);
    state.counters["p99_us"] = benchmark::Counter(pct(0.99), benchmark::Counter::kAvgThreads);
    state.counters["max_us"] = benchmark::Counter(us.back(), benchmark::Counter::kAvgThreads);
  }
  modbus_close(ctx);
  modbus_free(ctx);
}
BENCHMARK(BM_ModbusRoundTripLatency)->Threads(1)->Threads(4)->Threads(8)->UseRealTime();

void BM_SeqlockPublish(benchmark::State& state) {
  SeqlockSnapshot<RobotReport> board;
  RobotReport r;
  for (auto _ : state) {
    ++r.job_id;
    board.publish(r);
    benchmark::ClobberMemory();
  }
}
BENCHMARK(BM_SeqlockPublish);

void BM_SeqlockRead(benchmark::State& state) {
  SeqlockSnapshot<RobotReport> board;
  board.publish(RobotReport{});
  for (auto _ : state) benchmark::DoNotOptimize(board.read());
}
BENCHMARK(BM_SeqlockRead);

void BM_RequestGuardFc17(benchmark::State& state) {
  const std::uint8_t frame[] = {0, 1, 0, 0, 0, 15, 0xff, 0x17, 0, 8, 0, 28, 0, 1, 0, 2, 4, 0, 5, 0, 6};
  const RegisterPolicy policy{64, 0, 4};
  for (auto _ : state) benchmark::DoNotOptimize(check_request(frame, policy));
}
BENCHMARK(BM_RequestGuardFc17);

}  // namespace

BENCHMARK_MAIN();
