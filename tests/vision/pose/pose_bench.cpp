// Pose refinement per candidate (1 and 2 views) on the simulated cell: time and per-axis
// accuracy. Each benchmark iteration refines one candidate: the next (part, seed) pair, the
// part at a fixed tilted pose, the start perturbed by +-3 mm / up to 5 degrees. Counters are
// mean absolute errors over all candidates run (the paper's Table 2 columns):
//   tx_mm ty_mm tz_mm (part centre, view 0 camera axes), rx_deg ry_deg rz_deg (rotation vector
//   of R_est R_true^T), plus converged fraction, outer iterations and model renders.
// Edges: edges=0 noise-free occluding edges of a depth render, edges=1 the real MFC render
// through DepthEdgeExtractor.
//   build/<preset>/bench/bench_vision_pose --benchmark_format=console
#include "vision/pose/pose_refiner.hpp"

#include "pose_scenes.hpp"

#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstdlib>
#include <memory>

using namespace mfcd::vision;
using namespace mfcd::vision::testing;

namespace {

struct Candidate {
  std::string part;
  PoseModel model;
  cv::Vec3d centre;
  RigidTransform truth;
  std::vector<DepthEdges> edges;
  std::unique_ptr<PoseRefiner> refiner;
};

struct Cell {
  CameraConfig config = sim_config();
  MfcRenderer renderer{config};
  int floor = renderer.add_mesh(make_plane(2000));
  std::vector<std::pair<std::string, Mesh>> meshes;
  Cell() {
    meshes.emplace_back("box", make_box(40, 28, 18));
    for (const auto& f : part_stls()) meshes.emplace_back(f.stem().string(), load_mesh(f));
  }
};

// MFC_POSE_BENCH_VERBOSE=1 prints every candidate's errors to stderr.
bool verbose() {
  static const bool v = std::getenv("MFC_POSE_BENCH_VERBOSE") != nullptr;
  return v;
}

Cell& cell() {
  static Cell c;
  return c;
}

std::vector<Candidate> make_candidates(int views, bool mfc) {
  Cell& c = cell();
  std::vector<Candidate> out;
  for (const auto& [name, mesh] : c.meshes) {
    Candidate k;
    k.part = name;
    k.model = pose_model(c.renderer.add_mesh(mesh), mesh);
    k.centre = 0.5 * (k.model.bbox_min + k.model.bbox_max);
    k.truth = {rotation_from_angle_axis({0.3, -0.2, 0.9}), {8, -6, 305}};
    k.truth.t -= k.truth.R * k.centre;  // the part's centre at (8, -6, 305)
    std::vector<RigidTransform> cams{RigidTransform{}};
    if (views > 1) cams.push_back(second_view(k.truth.apply(k.centre), {0.05, 0.55, 0.1}, 300));
    const RigidTransform floor_pose{cv::Matx33d::eye(), {0, 0, k.truth.apply(k.centre)[2] + 45}};
    for (size_t v = 0; v < cams.size(); ++v) {
      const RigidTransform p = cams[v] * k.truth, fl = cams[v] * floor_pose;
      const std::vector<ScenePart> parts{{c.floor, fl.R, fl.t, Material::matte(0.5f)},
                                         {k.model.mesh_id, p.R, p.t, Material::matte(0.8f)}};
      k.edges.push_back(mfc ? mfc_depth_edges(c.renderer, c.config, parts, 21 + v)
                            : rendered_depth_edges(c.renderer, c.config.camera, parts));
    }
    std::vector<RefinementView> rv;
    for (size_t v = 0; v < cams.size(); ++v) rv.push_back({&k.edges[v], c.config.camera, cams[v]});
    k.refiner = std::make_unique<PoseRefiner>(c.renderer);
    k.refiner->prepare(rv);
    out.push_back(std::move(k));
  }
  return out;
}

void BM_RefineCandidate(benchmark::State& state) {
  const int views = static_cast<int>(state.range(0));
  const bool mfc = state.range(1) != 0;
  std::vector<Candidate> cands = make_candidates(views, mfc);
  double sum_t[3] = {0, 0, 0}, sum_r[3] = {0, 0, 0}, converged = 0, iterations = 0, renders = 0, n = 0;
  uint32_t seed = 0;
  for (auto _ : state) {
    Candidate& k = cands[static_cast<size_t>(seed) % cands.size()];
    state.PauseTiming();
    std::mt19937 rng(1000 + seed++);
    const RigidTransform start = perturb(k.truth, k.centre, rng, 3.0, 5.0);
    state.ResumeTiming();
    const RefinementResult r = k.refiner->refine(k.model, start);
    state.PauseTiming();
    const AxisErrors e = axis_errors(r.pose, k.truth, k.centre);
    for (int i = 0; i < 3; ++i) {
      sum_t[i] += std::abs(e.t[i]);
      sum_r[i] += std::abs(e.r[i]);
    }
    if (verbose())
      std::fprintf(stderr,
                   "%-8s views %d edges %d seed %u: t %+.3f %+.3f %+.3f mm r %+.3f %+.3f %+.3f deg cost %.2f px inl "
                   "%.2f it %d renders %d%s\n",
                   k.part.c_str(), views, mfc ? 1 : 0, seed - 1, e.t[0], e.t[1], e.t[2], e.r[0], e.r[1], e.r[2],
                   r.mean_cost_px, r.inlier_fraction, r.iterations, r.renders, r.converged ? " converged" : "");
    converged += r.converged;
    iterations += r.iterations;
    renders += r.renders;
    ++n;
    state.ResumeTiming();
  }
  const char* tn[3] = {"tx_mm", "ty_mm", "tz_mm"};
  const char* rn[3] = {"rx_deg", "ry_deg", "rz_deg"};
  for (int i = 0; i < 3; ++i) {
    state.counters[tn[i]] = sum_t[i] / n;
    state.counters[rn[i]] = sum_r[i] / n;
  }
  state.counters["converged"] = converged / n;
  state.counters["iterations"] = iterations / n;
  state.counters["renders"] = renders / n;
  state.counters["parts"] = static_cast<double>(cands.size());
}
// 4 seeds per part (box + the parts' STLs when built).
BENCHMARK(BM_RefineCandidate)
    ->ArgNames({"views", "edges"})
    ->Args({1, 0})
    ->Args({2, 0})
    ->Args({1, 1})
    ->Args({2, 1})
    ->Iterations(28)
    ->Unit(benchmark::kMillisecond);

// One model edge sampling (window render + occluding edges + back-projection).
void BM_ModelEdgeSample(benchmark::State& state) {
  Cell& c = cell();
  const Mesh box = make_box(40, 28, 18);
  const PoseModel model = pose_model(c.renderer.add_mesh(box), box);
  ModelEdgeSampler sampler(c.renderer);
  std::vector<ModelEdgePoint> pts;
  const RigidTransform pose{rotation_from_angle_axis({0.3, -0.2, 0.9}), {8, -6, 305}};
  for (auto _ : state) {
    sampler.sample(model, pose, c.config.camera, pts);
    benchmark::DoNotOptimize(pts.data());
  }
  state.counters["points"] = static_cast<double>(pts.size());
}
BENCHMARK(BM_ModelEdgeSample)->Unit(benchmark::kMillisecond);

// prepare(): indexing one 640x480 view's edges (once per frame set, shared by candidates).
void BM_PrepareView(benchmark::State& state) {
  Cell& c = cell();
  std::vector<Candidate> cands = make_candidates(1, true);
  RefinementView v{&cands[0].edges[0], c.config.camera, {}};
  PoseRefiner refiner(c.renderer);
  for (auto _ : state) refiner.prepare(std::span(&v, 1));
}
BENCHMARK(BM_PrepareView)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();

namespace {
void BM_RenderDepthWindow(benchmark::State& state) {
  Cell& c = cell();
  const Mesh box = make_box(40, 28, 18);
  const int id = c.renderer.add_mesh(box);
  const int s = static_cast<int>(state.range(0));
  c.renderer.set_camera(c.config.camera.cropped(cv::Rect(320 - s / 2, 240 - s / 2, s, s)));
  std::vector<ScenePart> parts{{id, rotation_from_angle_axis({0.3, -0.2, 0.9}), {0, 0, 305}, {}}};
  cv::Mat1f depth;
  cv::Mat1b index;
  for (auto _ : state) c.renderer.render_depth(parts, depth, index);
}
BENCHMARK(BM_RenderDepthWindow)->Arg(32)->Arg(64)->Arg(128)->Arg(256)->Arg(480)->Unit(benchmark::kMillisecond);
}  // namespace
