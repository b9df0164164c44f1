// Sequencer overhead per FrameSet on the simulated backends. The renderer is replaced by one that only
// writes the tag, so the figure is the sequencer + backend bookkeeping, not image synthesis.
// Allocations are counted by alloc_counter.cpp (global operator new replaced in this binary) and
// reported as the "allocs_per_set" counter; steady state must show 0.
#include <benchmark/benchmark.h>

#include "alloc_counter.hpp"
#include "mfcd/hal/sequencer.hpp"
#include "mfcd/hal/simulated.hpp"

namespace {
using namespace mfcd::hal;

class TagOnlyRenderer final : public SceneRenderer {
 public:
  void render(LedMask lit, std::uint64_t index, Image& out) override {
    out.data()[0] = lit;
    out.data()[1] = static_cast<std::uint8_t>(index);
  }
};

void BM_SequencerFrameSet(benchmark::State& state) {
  const int width = static_cast<int>(state.range(0));
  SimulatedLightRing ring;
  TagOnlyRenderer renderer;
  SimulatedCamera camera({{width, width * 3 / 4, 8}}, ring, &renderer);
  MfcSequencer seq(camera, ring);
  seq.configure();
  seq.activate();
  seq.read();
  const std::uint64_t before = mfcd::hal::test::allocation_count();
  for (auto _ : state) benchmark::DoNotOptimize(seq.read().sequence);
  const std::uint64_t allocs = mfcd::hal::test::allocation_count() - before;
  state.counters["allocs_per_set"] =
      benchmark::Counter(static_cast<double>(allocs) / static_cast<double>(state.iterations()));
  state.counters["frames_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()) * FrameSet::kSlots, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_SequencerFrameSet)->Arg(64)->Arg(640)->Unit(benchmark::kMicrosecond)->MeasureProcessCPUTime();

// With the built-in pattern renderer (what the unit tests use) for scale.
void BM_SequencerFrameSetPatternRenderer(benchmark::State& state) {
  SimulatedLightRing ring;
  SimulatedCamera camera({{640, 480, 8}}, ring);
  MfcSequencer seq(camera, ring);
  seq.configure();
  seq.activate();
  seq.read();
  const std::uint64_t before = mfcd::hal::test::allocation_count();
  for (auto _ : state) benchmark::DoNotOptimize(seq.read().sequence);
  state.counters["allocs_per_set"] = benchmark::Counter(
      static_cast<double>(mfcd::hal::test::allocation_count() - before) / static_cast<double>(state.iterations()));
}
BENCHMARK(BM_SequencerFrameSetPatternRenderer)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();

}  // namespace

BENCHMARK_MAIN();
