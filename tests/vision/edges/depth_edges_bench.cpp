// Depth-edge extraction on one simulated 640x480 MFC frame set (8 flashes + ambient).
#include "vision/edges/depth_edges.hpp"

#include "scenes.hpp"

#include <benchmark/benchmark.h>

using namespace mfcd::vision;

namespace {

void BM_DepthEdges640x480(benchmark::State& state) {
  const CameraConfig cfg = load_camera_config(MFC_SOURCE_DIR "/config/camera-sim.yaml");
  MfcRenderer r(cfg);
  const testing::SceneMeshes meshes(r);
  MfcRender out;
  r.render(testing::random_scene(meshes, 1, true), out);
  DepthEdgeExtractor extractor(cfg.camera, cfg.flashes);
  DepthEdges edges;
  for (auto _ : state) {
    extractor.extract(out.frames, edges);
    benchmark::DoNotOptimize(edges.edges.data);
  }
}
BENCHMARK(BM_DepthEdges640x480)->Unit(benchmark::kMillisecond);

void BM_Canny640x480(benchmark::State& state) {
  const CameraConfig cfg = load_camera_config(MFC_SOURCE_DIR "/config/camera-sim.yaml");
  MfcRenderer r(cfg);
  const testing::SceneMeshes meshes(r);
  MfcRender out;
  r.render(testing::random_scene(meshes, 1, true), out);
  CannyEdgeDetector canny(30, 90);
  DepthEdges edges;
  for (auto _ : state) canny.detect(out.frames.ambient, edges);
}
BENCHMARK(BM_Canny640x480)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
