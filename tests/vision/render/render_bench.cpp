// Per-view cost of the simulated MFC: 8 flash images + ambient + depth + part index.
#include "vision/render/mfc_renderer.hpp"

#include <benchmark/benchmark.h>

using namespace mfcd::vision;

namespace {

std::vector<ScenePart> scene(MfcRenderer& r) {
  const cv::Matx33d R(0.9, -0.3, 0.3, 0.36, 0.93, -0.08, -0.26, 0.18, 0.95);  // about 25 deg tilt
  return {{r.add_mesh(make_plane(800)), cv::Matx33d::eye(), {0, 0, 330}, Material::matte(0.5f)},
          {r.add_mesh(make_cylinder(25, 30, 128)), R, {0, 0, 305}, Material::matte()}};
}

void BM_RenderMfcFullFrame(benchmark::State& state) {
  RenderOptions opt;
  opt.noise.enabled = state.range(0) != 0;
  MfcRenderer r(load_camera_config(MFC_SOURCE_DIR "/config/camera-sim.yaml"), opt);
  const auto parts = scene(r);
  MfcRender out;
  for (auto _ : state) r.render(parts, out);
  state.SetLabel(opt.noise.enabled ? "640x480, noise" : "640x480, no noise");
}
BENCHMARK(BM_RenderMfcFullFrame)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// Template generation renders only a window around the part; the second argument 1 fills the
// whole shadow maps instead of the texels the window reads (the same pixels, the old cost).
void BM_RenderMfcWindow(benchmark::State& state) {
  RenderOptions opt;
  opt.noise.enabled = false;
  opt.fill_whole_shadow_maps = state.range(1) != 0;
  const CameraConfig cfg = load_camera_config(MFC_SOURCE_DIR "/config/camera-sim.yaml");
  MfcRenderer r(cfg, opt);
  const auto parts = scene(r);
  const int side = static_cast<int>(state.range(0));
  r.set_camera(cfg.camera.cropped({320 - side / 2, 240 - side / 2, side, side}));
  MfcRender out;
  for (auto _ : state) r.render(parts, out);
  state.SetLabel(std::to_string(side) + "x" + std::to_string(side) + " window, no noise" +
                 (opt.fill_whole_shadow_maps ? ", whole shadow maps" : ""));
}
BENCHMARK(BM_RenderMfcWindow)
    ->Args({128, 0})
    ->Args({128, 1})
    ->Args({256, 0})
    ->Args({256, 1})
    ->Unit(benchmark::kMillisecond);

// A 401x401 window as the teacher renders it (the part first, a background plane that casts no
// shadow), drawn whole or only in a centred region (MfcRenderer::render's `region`: the box
// that can hold the part and its shadows), lit per pixel (deferred, 0) or per fragment
// (forward, 1).
void BM_RenderMfcRegion(benchmark::State& state) {
  RenderOptions opt;
  opt.noise.enabled = false;
  opt.deferred_shading = state.range(1) == 0;
  const CameraConfig cfg = load_camera_config(MFC_SOURCE_DIR "/config/camera-sim.yaml");
  MfcRenderer r(cfg, opt);
  std::vector<ScenePart> parts = scene(r);
  parts[0].casts_shadows = false;
  std::swap(parts[0], parts[1]);
  constexpr int kWindow = 401;
  r.set_camera(cfg.camera.cropped({320 - kWindow / 2, 240 - kWindow / 2, kWindow, kWindow}));
  const int side = static_cast<int>(state.range(0));
  const cv::Rect region((kWindow - side) / 2, (kWindow - side) / 2, side, side);
  MfcRender out;
  for (auto _ : state) r.render(parts, out, 1, region);
  state.SetLabel(std::to_string(side) + "x" + std::to_string(side) + " region of a 401x401 window, " +
                 (opt.deferred_shading ? "deferred" : "forward"));
}
BENCHMARK(BM_RenderMfcRegion)->ArgsProduct({{401, 283, 200}, {0, 1}})->Unit(benchmark::kMillisecond);

void BM_RenderDepthOnly(benchmark::State& state) {
  MfcRenderer r(load_camera_config(MFC_SOURCE_DIR "/config/camera-sim.yaml"));
  const auto parts = scene(r);
  cv::Mat1f depth;
  cv::Mat1b index;
  for (auto _ : state) r.render_depth(parts, depth, index);
}
BENCHMARK(BM_RenderDepthOnly)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
