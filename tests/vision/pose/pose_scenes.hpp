#pragma once
// Scenes shared by the pose tests and benchmark: a part on a floor seen by the simulated MFC
// (config/camera-sim.yaml) from view 0 and, for two-view refinement, from a second camera
// position looking at the part from another direction (the paper's second robot position:
// part near the image centre, different out-of-plane angle).
#include "vision/edges/depth_edges.hpp"
#include "vision/edges/edge_evaluation.hpp"
#include "vision/pose/model_edges.hpp"
#include "vision/pose/pose_refiner.hpp"
#include "vision/render/mfc_renderer.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

namespace mfcd::vision::testing {

inline CameraConfig sim_config() { return load_camera_config(MFC_SOURCE_DIR "/config/camera-sim.yaml"); }

// The parts' STLs built from config/parts/*.scad (empty when OpenSCAD is not installed).
inline std::vector<std::filesystem::path> part_stls() {
  std::vector<std::filesystem::path> out;
  const std::filesystem::path dir = MFC_BINARY_DIR "/parts";
  if (!std::filesystem::is_directory(dir)) return out;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.path().extension() == ".stl") out.push_back(e.path());
  std::sort(out.begin(), out.end());
  return out;
}

// Reference (view 0 camera) -> a camera that sees `centre` at its image centre from `distance`
// along a direction tilted by angle-axis `tilt` (radians) from view 0's optical axis.
inline RigidTransform second_view(const cv::Vec3d& centre, const cv::Vec3d& tilt, double distance) {
  RigidTransform v;
  v.R = rotation_from_angle_axis(tilt);
  v.t = cv::Vec3d(0, 0, distance) - v.R * centre;
  return v;
}

// Per-axis pose error: translation difference (mm) and the rotation vector of
// R_est * R_true^T (deg), both in the reference frame.
struct AxisErrors {
  double t[3] = {0, 0, 0}, r[3] = {0, 0, 0};
  double max_t() const { return std::max({std::abs(t[0]), std::abs(t[1]), std::abs(t[2])}); }
  double max_r() const { return std::max({std::abs(r[0]), std::abs(r[1]), std::abs(r[2])}); }
};
inline AxisErrors axis_errors(const RigidTransform& est, const RigidTransform& truth, const cv::Vec3d& centre) {
  AxisErrors e;
  // Translation of the part's centre (what a grasp cares about), not of the model origin.
  const cv::Vec3d dt = est.apply(centre) - truth.apply(centre);
  const cv::Matx33d dR = est.R * truth.R.t();
  const double angle = rotation_angle(dR);
  cv::Vec3d axis(dR(2, 1) - dR(1, 2), dR(0, 2) - dR(2, 0), dR(1, 0) - dR(0, 1));
  const double s = cv::norm(axis);
  const cv::Vec3d w = s > 1e-15 ? axis * (angle / s) : cv::Vec3d(0, 0, 0);
  for (int i = 0; i < 3; ++i) {
    e.t[i] = dt[i];
    e.r[i] = degrees(w[i]);
  }
  return e;
}

// Random perturbation: each translation axis uniform in +-max_mm, rotation about a random axis
// through the part's centre by an angle uniform in [max_deg / 2, max_deg].
inline RigidTransform perturb(const RigidTransform& pose, const cv::Vec3d& centre, std::mt19937& rng, double max_mm,
                              double max_deg) {
  std::uniform_real_distribution<double> u(-1, 1), half(0.5, 1);
  cv::Vec3d axis(u(rng), u(rng), u(rng));
  axis /= cv::norm(axis);
  const cv::Matx33d dR = rotation_from_angle_axis(axis * radians(max_deg * half(rng)));
  RigidTransform out;
  out.R = dR * pose.R;
  const cv::Vec3d c = pose.apply(centre) + cv::Vec3d(max_mm * u(rng), max_mm * u(rng), max_mm * u(rng));
  out.t = c - out.R * centre;
  return out;
}

// Noise-free depth edges of a scene: occluding edges of its depth render (near side; grazing
// faces are no edges, as for the multi-flash camera), directions from the pixel chains.
inline DepthEdges rendered_depth_edges(MfcRenderer& renderer, const PinholeCamera& camera,
                                       const std::vector<ScenePart>& parts, float min_jump_mm = 2.0f) {
  renderer.set_camera(camera);
  cv::Mat1f depth;
  cv::Mat1b index;
  renderer.render_depth(parts, depth, index);
  DepthEdges e;
  occluding_edges(depth, min_jump_mm, ModelEdgeParams{}.min_jump_ratio, e.edges, &index);
  edge_tangents(e.edges, e.direction);
  return e;
}

// Depth edges the real way: a noisy MFC render through DepthEdgeExtractor.
inline DepthEdges mfc_depth_edges(MfcRenderer& renderer, const CameraConfig& config,
                                  const std::vector<ScenePart>& parts, uint64_t seed) {
  renderer.set_camera(config.camera);
  MfcRender render;
  renderer.render(parts, render, seed);
  DepthEdgeExtractor extractor(config.camera, config.flashes);
  DepthEdges e;
  extractor.extract(render.frames, e);
  return e;
}

}  // namespace mfcd::vision::testing
