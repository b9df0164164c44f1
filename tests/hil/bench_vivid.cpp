// Sequencer overhead per FrameSet on real drivers (vivid + gpio-sim, inside the HIL VM). CPU time is
// the process's (the sequencer sleeps in poll() while vivid produces frames, so CPU time is the
// overhead, wall time is bound by vivid's frame rate). Allocations counted by alloc_counter.cpp.
#include <benchmark/benchmark.h>
#include <gpiod.h>
#include <unistd.h>

#include "../hal/alloc_counter.hpp"
#include "mfcd/hal/gpiod_light_ring.hpp"
#include "mfcd/hal/sequencer.hpp"
#include "mfcd/hal/v4l2_camera.hpp"

namespace {
using namespace mfcd::hal;

void BM_SequencerFrameSetVivid(benchmark::State& state) {
  gpiod_chip* chip = gpiod_chip_open_by_label("mfc-leds");
  if (!chip || ::access("/dev/video0", F_OK) != 0) {
    if (chip) gpiod_chip_close(chip);
    state.SkipWithError("needs vivid and gpio-sim 'mfc-leds' (run inside the HIL VM: tools/mfc hil)");
    return;
  }
  gpiod_chip_close(chip);
  V4L2CameraConfig cfg;
  cfg.width = 320;
  cfg.height = 180;
  V4L2Camera camera(cfg);
  GpiodLightRing ring({"mfc-leds", {0, 1, 2, 3, 4, 5, 6, 7}, false, "mfcd-bench"});
  MfcSequencer seq(camera, ring);
  seq.configure();
  seq.activate();
  seq.read();
  const std::uint64_t before = mfcd::hal::test::allocation_count();
  for (auto _ : state) benchmark::DoNotOptimize(seq.read().sequence);
  state.counters["allocs_per_set"] = benchmark::Counter(
      static_cast<double>(mfcd::hal::test::allocation_count() - before) / static_cast<double>(state.iterations()));
  state.counters["stale_per_set"] =
      benchmark::Counter(static_cast<double>(seq.stats().stale_discarded) / static_cast<double>(state.iterations() + 1));
}
BENCHMARK(BM_SequencerFrameSetVivid)->Iterations(10)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
