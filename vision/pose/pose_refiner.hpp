#pragma once
// Multi-view pose refinement (paper Sec. 4.5): ICP-like alternation of
//   (a) model edge points at the current pose, per view (ModelEdgeSampler: render + depth
//       discontinuities, back-projected to the model frame),
//   (b) correspondences to the view's detected edges by the directional chamfer criterion
//       (Eq. 21, DirectionalEdgeIndex), gated,
//   (c) a Ceres least-squares update of the 6-DoF pose over all active views (Eq. 22 with
//       point-to-line residuals and a Huber loss; docs/pose.md explains the choices).
// Schedule: view 0 alone for the first iterations, then all views jointly.
//
// Frames: the pose is model -> reference (e.g. view 0's camera, or a world/robot frame);
// each view gives reference -> its camera and its own pinhole. Units: mm, radians inside,
// pixels for costs.
//
// Usage per frame set: prepare(views) once (indexes each view's edges), then refine() per
// candidate. Buffers are reused between calls; not thread-safe (borrows an MfcRenderer whose
// EGL context belongs to the calling thread).

#include "vision/edges/depth_edges.hpp"
#include "vision/pose/edge_correspondence.hpp"
#include "vision/pose/model_edges.hpp"
#include "vision/pose/rigid_transform.hpp"
#include "vision/render/mfc_renderer.hpp"

#include <chrono>
#include <memory>
#include <span>
#include <vector>

namespace mfcd::vision {

struct RefinementView {
  const DepthEdges* edges = nullptr;   // borrowed; must outlive the refine() calls
  PinholeCamera camera;                // edges.size() must equal camera.image_size
  RigidTransform reference_to_camera;  // identity when the reference frame is this camera's
};

struct RefinerParams {
  int max_iterations = 20;                            // outer (correspondence) iterations; the paper: ~20 suffice
  int first_view_iterations = 2;                      // view 0 alone for these, then all views
  int solver_iterations = 4;                          // Ceres (Levenberg-Marquardt) iterations per outer iteration
  double lambda_px_per_rad = kDefaultLambdaPxPerRad;  // Eq. 21 orientation weight (6 deg = 1 px)
  // Re-estimate the detected edges' directions from their pixel chains (edge_tangents, the
  // estimator used for the model's edges) instead of using DepthEdges::direction: the
  // extractors' per-pixel gradient directions scatter by 10-20 degrees on depth edges, which
  // Eq. 21 charges 2-3 px for.
  bool edge_directions_from_chains = true;
  double initial_gate_px = 24;     // correspondence gate (max Eq. 21 cost) at iteration 0 ...
  double final_gate_px = 4;        // ... shrinking geometrically to this
  int gate_shrink_iterations = 8;  // iterations over which the gate shrinks
  enum class Loss { huber, cauchy };
  Loss loss = Loss::huber;     // robust loss on the point-to-line residuals ...
  double loss_scale_px = 1.0;  // ... and its scale
  // Largest pose change one iteration of the view-0-only phase may make (the update is scaled
  // down to fit). A single view leaves some directions weak (depth, tilt of flat parts), and
  // a long step on view 0's correspondences alone can walk into a false minimum of the
  // silhouette (e.g. a thick box's top outline taken for its bottom one) before the other
  // views are consulted. 0 = no limit. The joint phase is not limited.
  double first_view_max_step_mm = 1.0;
  double first_view_max_step_deg = 1.0;
  // Pose changes are measured where they matter: the mean image displacement (px) of the
  // view's model edge points between two poses. Motions the edges cannot see (a cylinder
  // turning about its axis) count as none.
  // Model edge points are re-rendered when the pose has moved them by rerender_px since their
  // render; in between they are reprojected (the contour generator moves slowly with the pose,
  // and a render is the costliest step: ~3-6 ms of llvmpipe per view for a 256 px window).
  double rerender_px = 4.0;
  // Converged when an iteration (after the joint phase began) moves the points less than
  // converged_px and they were rendered within fresh_px of the pose; when they were not, they
  // are rendered again and the iterations go on (stale points bias the pose by a few 0.01 mm).
  double converged_px = 0.02;
  double fresh_px = 0.1;
  int min_correspondences = 12;  // fewer in an iteration: refinement fails
  // Final evaluation: a model point is an inlier when its Eq. 21 cost is <= inlier_cost_px;
  // costs are truncated at final_gate_px for the mean.
  double inlier_cost_px = 2.0;
  ModelEdgeParams model_edges;

  void validate() const;  // throws std::invalid_argument naming the field
};

struct RefinementResult {
  RigidTransform pose;         // refined model -> reference
  double mean_cost_px = 0;     // mean Eq. 21 cost (truncated) of the model edges at `pose`
  double inlier_fraction = 0;  // model edge points with cost <= inlier_cost_px
  double score = 0;            // [0, 1]: inlier_fraction * (1 - mean_cost_px / final_gate_px)
  int iterations = 0;          // outer iterations run
  int model_points = 0;        // model edge points evaluated at the final pose (all views)
  int renders = 0;             // model renders, including the final evaluation
  bool converged = false;      // the pose stopped moving before max_iterations
  bool deadline_hit = false;   // cut short by the deadline: best-so-far pose
  bool failed = false;         // too few correspondences (pose = last good estimate)
};

class PoseRefiner {
 public:
  using Clock = std::chrono::steady_clock;

  PoseRefiner(MfcRenderer& renderer, const RefinerParams& params = {});
  ~PoseRefiner();
  PoseRefiner(const PoseRefiner&) = delete;
  PoseRefiner& operator=(const PoseRefiner&) = delete;

  // Indexes the views' edges (once per frame set). Throws std::invalid_argument naming the
  // view and the reason: no views, a null/empty edge map, size mismatch with its camera, or a
  // view without any edge pixel.
  void prepare(std::span<const RefinementView> views);

  // Refines `initial` (model -> reference) of `model`. Views prepared by prepare(). Returns
  // the best-so-far pose with deadline_hit when `deadline` passes between iterations.
  RefinementResult refine(const PoseModel& model, const RigidTransform& initial,
                          Clock::time_point deadline = Clock::time_point::max());

  // Mean truncated Eq. 21 cost and inlier fraction of the model edges at `pose` (renders).
  RefinementResult evaluate(const PoseModel& model, const RigidTransform& pose);

  const RefinerParams& params() const { return params_; }
  size_t view_count() const;

 private:
  struct Impl;
  double gate_at(int iteration) const;
  void evaluate_into(const PoseModel& model, RefinementResult& result);

  MfcRenderer& renderer_;
  RefinerParams params_;
  ModelEdgeSampler sampler_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mfcd::vision
