#pragma once
// 6-DoF fit of a search hypothesis with the template's own model points (paper Sec. 4.5 without
// rendering): the matched template view carries, for every edge pixel, the visible model point
// it images, so a hypothesis can be moved off the sampled views continuously. Each iteration
// projects the view's points at the current pose, pairs them with the image's edge pixels by the
// directional chamfer criterion (Eq. 21, DirectionalEdgeIndex; with depth edges, only edges
// whose near side is the part's: edge polarity) and takes one Gauss-Newton step
// of the point-to-line error with a Huber weight. When the pose has turned closer to another
// template view (symmetry-aware), that view's points are used from then on.
//
// Why: K = 300 views are up to ~6 degrees apart, and at that offset the true pose of a part
// scores 2.5-3 px of mean chamfer cost even when it is alone in the image, no better than the
// clutter of a full bin. After this fit the truth scores near the edge noise, so hypotheses
// are ranked by the fitted score. The render-based PoseRefiner then polishes the best few.
//
// prepare() once per image (indexes the edges); fit()/evaluate() are const and may run on
// several threads at once, each with its own Workspace.

#include "vision/camera/camera.hpp"
#include "vision/common/convex_region.hpp"
#include "vision/edges/depth_edges.hpp"
#include "vision/model/surface_grid.hpp"
#include "vision/pose/coarse_pose.hpp"
#include "vision/pose/edge_correspondence.hpp"
#include "vision/pose/rigid_transform.hpp"
#include "vision/templates/template_database.hpp"

#include <cstdint>
#include <limits>
#include <numbers>
#include <vector>

namespace mfcd::vision {

struct TemplateFitParams {
  int max_points = 160;         // template points used per view (evenly subsampled)
  int iterations = 8;           // Gauss-Newton steps
  double initial_gate_px = 10;  // correspondence gate (Eq. 21 cost) at the first step ...
  double final_gate_px = 3;     // ... shrinking geometrically to this at the last
  double huber_px = 1.0;        // Huber weight scale of the point-to-line residuals
  double damping = 1e-3;        // Levenberg-Marquardt damping, relative to the diagonal
  double score_gate_px = 4;     // evaluation: costs truncated here ...
  double inlier_cost_px = 2;    // ... and a point is an inlier at or below this
  double lambda_px_per_rad = kDefaultLambdaPxPerRad;
  int min_correspondences = 12;  // fewer: the step is skipped and the fit ends
  // Move each placed point by the difference between the query's and the views' edge offset
  // profiles for its direction (TemplateDatabase::query_edge_offset, EdgeOffsetProfile): without
  // it a part turned in the image is fitted up to ~2 mm too near (docs/pose.md, "Edge offset
  // profiles"). No effect on databases without profiles or on intensity (Canny) edges.
  bool edge_offset_correction = true;
  // fit() scores its result (mean cost, inliers, coverage); false leaves those at 0, for a refit
  // whose pose alone is wanted.
  bool score_result = true;
  void validate() const;  // throws std::invalid_argument naming the field
};

struct TemplateFitResult {
  RigidPose pose;              // model -> camera
  int view = -1;               // template view whose points were used last
  double mean_cost_px = 0;     // mean Eq. 21 cost, truncated at score_gate_px
  double inlier_fraction = 0;  // points with cost <= inlier_cost_px
  double score = 0;            // inlier_fraction * (1 - mean_cost_px / score_gate_px), [0, 1]
  // The converse check: the fraction of the image's edge pixels inside the part's outline at
  // the pose that lie within 2 px of one of the view's points. Chamfer costs only ask whether
  // the template's edges are in the image; a flat part seen from the back (fewer inner edges)
  // scores as well as its front there, but leaves the front's inner edges unexplained.
  double coverage = 0;
  int points = 0;      // template points evaluated
  int iterations = 0;  // steps taken
};

class TemplatePoseFit {
 public:
  // Per-thread buffers, reused between fits (no allocation once they have grown). Cache-line
  // aligned: the threads' workspaces lie side by side, and their vectors' ends change per point.
  struct alignas(64) Workspace {
    std::vector<cv::Vec3d> model;             // the view's points in use, model frame
    std::vector<float> angle;                 // their template tangent angles
    std::vector<cv::Vec2d> offset;            // detected edge pixel minus the model point's projection, template view
    std::vector<cv::Point> placed;            // coverage: all the view's points at the pose
    ConvexRegion region;                      // ... their hull and the pixels inside it
    std::vector<cv::Point2d> seen_a, seen_b;  // compare(): the two poses' points in the image
    std::vector<double> angle_a, angle_b;     // ... and their image tangent angles
    cv::Mat1b explained;                      // coverage mask, image size, kept zero outside use
  };

  explicit TemplatePoseFit(const TemplateFitParams& params = {});

  // Grows `ws` for every view of `db` on images of `image` size: fits, scores and comparisons of
  // them then allocate nothing, not even the first time (a search thread meets views in any order).
  void reserve(const TemplateDatabase& db, cv::Size image, Workspace& ws) const;

  // Indexes the image's edge pixels with tangent directions from their pixel chains (the
  // estimator the templates' directions come from). Throws std::invalid_argument on an empty map.
  void prepare(const DepthEdges& edges);
  // Takes `other`'s prepared image (its indexed edges) instead of preparing again: the same image
  // fitted with other params. Copies the index into this fitter's buffers (no allocation once
  // they have grown).
  void share_prepared(const TemplatePoseFit& other);

  TemplateFitResult fit(const TemplateDatabase& db, int view, const RigidPose& initial, const PinholeCamera& camera,
                        Workspace& ws) const;
  // The score of a pose with the given view's points, without moving it: at most `max_points` of
  // them, evenly subsampled (0: params().max_points, as fit() uses; kAllPoints: every one).
  static constexpr int kAllPoints = std::numeric_limits<int>::max();
  TemplateFitResult evaluate(const TemplateDatabase& db, int view, const RigidPose& pose, const PinholeCamera& camera,
                             Workspace& ws, int max_points = 0) const;

  // The fit of one pose seen in two images from two cameras with the same intrinsics (paper
  // Sec. 4.5: Eq. 22 summed over both views). `second` has the second image prepared; `motion`
  // maps the first camera's frame into the second's (p2 = motion.R p1 + motion.t, mm). Each step
  // pairs both images' points and solves one update for both: a pose that trades tilt for
  // distance in one view is held by the other. The pose stays in the first camera's frame;
  // `second` is how the second image sees and scores it. Both are scored as evaluate() does.
  struct TwoViewResult {
    TemplateFitResult first, second;
  };
  TwoViewResult fit_two_views(const TemplateDatabase& db, const RigidPose& initial, const PinholeCamera& camera,
                              const TemplatePoseFit& second, const RigidTransform& motion, Workspace& ws,
                              Workspace& ws_second) const;

  // The template view nearest to `pose` (by the direction the camera sees the part from) over
  // the turns the views were folded by (db.views_symmetry); `pose` is replaced by the symmetric
  // copy that view belongs to (the same placed part). Continuous symmetry: the views' meridian.
  static int nearest_view(const TemplateDatabase& db, const PinholeCamera& camera, RigidPose& pose);
  // The angle (radians) by which the image of the part at `pose` is turned in the image plane
  // relative to view `view`'s image: a view point's tangent at the pose is its own plus this.
  static double in_plane_angle(const TemplateDatabase& db, int view, const RigidPose& pose,
                               const PinholeCamera& camera);

  // Two fitted poses of one part at one place (e.g. a pose and its turn by 180 degrees about a
  // near-symmetry axis) judged where they differ: only the points of each that have no point of
  // the other within `apart_px` in the image, the share of those that find an image edge
  // (Eq. 21 cost <= inlier_cost_px) and their mean cost. Where the poses agree, the edges cannot
  // tell them apart.
  // `differs_a` / `differs_b` (per point of a's / b's view, e.g. from asymmetric_points) narrow
  // each side further to its flagged points.
  static constexpr double kCompareGatePx = 10;
  struct Difference {
    int only_a = 0, only_b = 0;       // points of each with no counterpart in the other
    double found_a = 0, found_b = 0;  // share of those on image edges
    // Their mean Eq. 21 cost, truncated at kCompareGatePx (kCompareGatePx when there are none):
    // how near edges they lie, also when few lie on one. A small feature fitted from a template
    // view a few degrees off its pose lands 2-5 px beside its edges, where the share found says
    // as little as for a feature with no edge near at all.
    double cost_a = kCompareGatePx, cost_b = kCompareGatePx;
  };
  Difference compare(const TemplateDatabase& db, const TemplateFitResult& a, const TemplateFitResult& b,
                     const PinholeCamera& camera, Workspace& ws, const std::vector<uint8_t>* differs_a = nullptr,
                     const std::vector<uint8_t>* differs_b = nullptr, double apart_px = 3.0) const;

  const TemplateFitParams& params() const { return params_; }

 private:
  // Loads the view's points, evenly subsampled to at most `max_points` (default: the params').
  void load_view(const TemplateDatabase& db, int view, const PinholeCamera& camera, Workspace& ws,
                 int max_points = 0) const;
  // The loaded view's points at `pose` in the image (with the edge offset) and their angles.
  void place_points(const TemplateDatabase& db, int view, const RigidPose& pose, const PinholeCamera& camera,
                    const Workspace& ws, std::vector<cv::Point2d>& seen, std::vector<double>& angle) const;
  void score(const TemplateDatabase& db, int view, const PinholeCamera& camera, Workspace& ws,
             TemplateFitResult& r) const;
  // The correspondence gate at step `step` of params().iterations: initial_gate_px shrinking
  // geometrically to final_gate_px.
  double gate_at(int step) const;
  // The damped step of normal equations H delta = -g (Levenberg-Marquardt, Cholesky); false when
  // they have no solution.
  bool solve_step(cv::Matx66d H, const cv::Vec6d& g, cv::Vec6d& delta) const;
  // One Gauss-Newton step's normal equations of the loaded view's points at `pose` (the update:
  // rotation about `centre_cam`, then translation, camera axes), added to H and g; with
  // `update_to_camera`, the update is another camera's and that rotation turns it into this
  // one's. Returns the points paired with an image edge within `gate`.
  int accumulate(const TemplateDatabase& db, int view, const RigidPose& pose, const cv::Vec3d& centre_cam,
                 const PinholeCamera& camera, double gate, const Workspace& ws, const cv::Matx33d* update_to_camera,
                 cv::Matx66d& H, cv::Vec6d& g) const;
  double coverage(const TemplateDatabase& db, int view, const RigidPose& pose, const PinholeCamera& camera,
                  Workspace& ws) const;

  // The query's edge offset profile when the correction applies to `db` (params, depth edges,
  // profiles present), else null.
  const EdgeOffsetProfile* query_offset(const TemplateDatabase& db) const;

  // The period of the tangent angles the index compares: 2 pi when oriented.
  double period() const { return index_.oriented() ? 2 * std::numbers::pi : std::numbers::pi; }

  TemplateFitParams params_;
  DepthEdges chain_edges_;
  cv::Mat1b edges_;  // the indexed edge map (shared)
  DirectionalEdgeIndex index_;
};

// The share of the edge pixels of `edges` inside the convex hull of `placed` (image pixels; the
// pixels ConvexRegion covers) that lie within 2 px of one of them: the converse of a chamfer
// cost. `region` and `explained` are scratch (the mask image-sized and zero, and left zero); no
// allocation once they have grown.
double explained_edge_fraction(const cv::Mat1b& edges, const std::vector<cv::Point>& placed, ConvexRegion& region,
                               cv::Mat1b& explained);

// The point-to-line residual of one template point and its 1x6 Jacobian with respect to the
// update (rotation w about the part centre, then translation of the centre), both in camera
// coordinates; exposed for the finite-difference test.
double point_to_line_residual(const RigidPose& pose, const cv::Vec3d& centre_cam, const cv::Vec3d& model_point,
                              const PinholeCamera& camera, const cv::Point2d& edge, const cv::Vec2d& normal,
                              cv::Matx16d* jacobian);

// Applies an update (w, tau) as fit() does: R <- exp(w) R about the part centre `centre_model`,
// the centre moved by tau (camera frame).
RigidPose apply_pose_update(const RigidPose& pose, const cv::Vec3d& centre_model, const cv::Vec6d& update);

// For a turn `turn` of the part about its centre (db.center_mm) that is a symmetry of the part but
// for some feature (the breaker's toggle under the half turn about z): per view, per point,
// whether the point's turned copy lies off the part's surface (`surface`, made from db.mesh),
// i.e. whether the point belongs to the feature that breaks the symmetry. Only those points can
// tell the pose from its turned twin; elsewhere the twin has edges of its own at the same place.
// `share`, when given, receives the flagged fraction of all points (near 1 for a turn that is no
// near-symmetry at all, e.g. a plate turned face down).
// `pivot_mm`: the model point the turn is about (default: db.center_mm).
std::vector<std::vector<uint8_t>> asymmetric_points(const TemplateDatabase& db, const SurfaceGrid& surface,
                                                    const cv::Matx33d& turn, double* share = nullptr,
                                                    const cv::Vec3d* pivot_mm = nullptr);
// The part's surface for asymmetric_points, to half a millimetre: the template points come from
// the depth buffer and every one of the six development parts' lies within that of the mesh, and
// a feature that breaks a symmetry by less (2 px at the working distance) would not show anyway.
SurfaceGrid part_surface(const TemplateDatabase& db);

}  // namespace mfcd::vision
