#pragma once
// The pipeline's state, shared by its stages' files (internal to vision/pipeline): the hits and
// hypotheses of a cycle, its buffers and settings (BinPickingPipeline::Impl), and the measures
// the stages share. The stages: search (search_stage.cpp), hypothesis fit (hypothesis_fit.cpp),
// ranking and the turn checks (ranking.cpp), candidates, refinement and grasp visibility
// (bin_picking_pipeline.cpp, process()).

#include "vision/dt3/directional_distance_transform.hpp"
#include "vision/idt3/integral_distance_transform.hpp"
#include "vision/lines/line_fitter.hpp"
#include "vision/pipeline/bin_picking_pipeline.hpp"
#include "vision/pipeline/cycle_budget.hpp"
#include "vision/pipeline/part_model.hpp"
#include "vision/pipeline/pipeline_parameters.hpp"
#include "vision/pipeline/turn_checks.hpp"
#include "vision/pose/coarse_pose.hpp"
#include "vision/pose/pose_refiner.hpp"
#include "vision/pose/rigid_transform.hpp"
#include "vision/pose/template_pose_fit.hpp"
#include "vision/render/mfc_renderer.hpp"
#include "vision/search/line_search.hpp"
#include "vision/search/nms.hpp"
#include "vision/search/oriented_template.hpp"
#include "vision/templates/template_database.hpp"

#include <opencv2/imgproc.hpp>

#include <omp.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>

namespace mfcd::vision {

using namespace detail;  // the pipeline's own parts: part_model.hpp, turn_checks.hpp

namespace detail {

class Stage;

using Clock = std::chrono::steady_clock;

struct Hit {
  int part = 0, view = 0, warp = 0;
  Candidate c;
  cv::Rect2d box;
};

// Best search cost first; ties broken by everything else, so that the order does not depend on
// which thread found what.
inline bool hit_order(const Hit& a, const Hit& b) {
  const uint64_t l = uint64_t(a.c.sum) * b.c.pixels, r = uint64_t(b.c.sum) * a.c.pixels;
  if (l != r) return l < r;
  if (a.part != b.part) return a.part < b.part;
  if (a.view != b.view) return a.view < b.view;
  if (a.warp != b.warp) return a.warp < b.warp;
  if (a.c.tx != b.c.tx) return a.c.tx < b.c.tx;
  return a.c.ty < b.c.ty;
}

inline double iou(const cv::Rect2d& a, const cv::Rect2d& b) {
  const double inter = (a & b).area();
  const double uni = a.area() + b.area() - inter;
  return uni > 0 ? inter / uni : 0;
}

// Weight of the image edges a template leaves unexplained: all of them unexplained costs as
// much as 3 px of mean chamfer distance.
inline constexpr double kUnexplainedPenaltyPx = 3.0;

// Hypotheses fitted even past the deadline (the best few by search cost): a late cycle still
// gives picks.
inline constexpr int kAlwaysFitted = 4;
// Views of each selected part searched even past the search's deadline (the first of the coarse
// pass, spread over the sphere).
inline constexpr size_t kAlwaysSearchedPerPart = 2;

// Largest change of the part's distance a hypothesis fit may make (fraction of the distance).
inline constexpr double kMaxFitDepthChange = 0.08;

// One view constrains depth weakly; a fit that walks far along the line of sight from the
// distance the image scale gave (fit_distance) has slid onto other edges.
inline bool moved_too_far_in_depth(const TemplateDatabase& db, const RigidPose& coarse, const RigidPose& fitted) {
  const double z0 = cv::norm(coarse.R * db.center_mm + coarse.t_mm);
  const double z1 = cv::norm(fitted.R * db.center_mm + fitted.t_mm);
  return std::abs(z1 - z0) > kMaxFitDepthChange * z0;
}

// The calling thread's OpenMP team size set for a scope and restored after. The stages that open
// their own parallel regions (depth edges, line fitting, DT3 / IDT3) take it from the calling
// thread, so a cycle under this runs every stage on PipelineConfig::threads threads, as the
// search and the fits do with theirs; 0 leaves the caller's setting.
class OmpThreadsInScope {
 public:
  explicit OmpThreadsInScope(int threads) : before_(omp_get_max_threads()) {
    if (threads > 0) omp_set_num_threads(threads);
  }
  ~OmpThreadsInScope() { omp_set_num_threads(before_); }
  OmpThreadsInScope(const OmpThreadsInScope&) = delete;
  OmpThreadsInScope& operator=(const OmpThreadsInScope&) = delete;

 private:
  int before_;
};

// Per-thread buffers of fit_distance: the warped template it scores, kept between warps and cycles.
// Cache-line aligned, as every per-thread workspace: the threads' workspaces lie side by side.
struct alignas(64) DistanceFitWorkspace {
  OrientedTemplate warped;
  std::vector<DigitalSegment> scratch;
};

// The order of std::stable_sort without its temporary buffer (allocated on every call): insertion
// sort, for the cycle's few dozen hypotheses.
template <class T, class Less>
void stable_sort_in_place(std::vector<T>& v, Less less, size_t first = 0) {
  for (size_t i = first + 1; i < v.size(); ++i)
    for (size_t j = i; j > first && less(v[j], v[j - 1]); --j) std::swap(v[j], v[j - 1]);
}

// Calls `at` with the image point of every edge point of `view` at `pose`, those behind the
// camera skipped (unrounded and unclipped: the caller decides which pixel it is and whether it is
// in the image).
template <class At>
void for_each_projected_point(const TemplateView& view, const RigidPose& pose, const PinholeCamera& camera, At at) {
  for (const TemplateEdgePoint& p : view.points) {
    const cv::Vec3d cam = pose.R * cv::Vec3d(p.model_mm[0], p.model_mm[1], p.model_mm[2]) + pose.t_mm;
    if (cam[2] > 0) at(camera.project(cam));
  }
}

// The fit's measures of a hypothesis (hypothesis_fit.cpp).
// The fraction of image edge pixels inside the placed template's outline (convex hull of its
// edge points) that lie within 2 px of a template edge point; scratch: the fit's workspace.
double explained_fraction(const TemplateView& view, const Warp& warp, int tx, int ty, const cv::Mat1b& edges,
                          TemplatePoseFit::Workspace& ws);
// The fitted view's edge points at the fitted distance.
double view_points(const TemplateFitResult& f, const TemplateDatabase& db);
// The rank of a fitted hypothesis: fit score - unexplained_weight x unexplained share
// + evidence_weight x ln(points found / 300).
double fitted_rank(const TemplateFitResult& f, const TemplateDatabase& db, const PipelineConfig& c);
// The local search of scale, in-plane angle and 3 px of translation around a search hit at the
// search's resolution `down`; `full` and the returned cost in full-resolution pixels.
double fit_distance(const LineSet& lines, const IntegralDistanceTransform& idt, int down, TemplatePlacement& full,
                    DistanceFitWorkspace& ws);

}  // namespace detail

struct BinPickingPipeline::Impl {
  CameraConfig camera;
  PipelineConfig config;
  LineFitter line_fitter;  // default LineFitParams, oriented as the templates' lines
  LineFitResult lines;     // this cycle's query lines (buffers reused)
  Dt3Params dt3_params;
  std::vector<PartModel> parts;
  // The loaded part type `obj_id`; std::invalid_argument when none is.
  const PartModel& part_of(int obj_id) const {
    for (const auto& p : parts)
      if (p.db.obj_id == obj_id) return p;
    throw std::invalid_argument("pipeline: no templates loaded for obj_id " + std::to_string(obj_id));
  }
  DepthEdgeExtractor extractor;
  DepthEdges edges;
  cv::Mat1b own_edges;        // grasp visibility: the pixels a candidate's own points explain (kept zero between uses)
  Dt3Params search_dt3;       // dt3_params in reduced pixels
  cv::Mat1b search_channels;  // the line fitter's channel map, reduced
  LineSet search_lines;       // the query lines, reduced
  DirectionalDistanceTransform dt3;
  IntegralDistanceTransform idt;
  ChamferCosts chamfer;  // baselines only
  // Refinement renders the model, so it needs a GL context bound to the thread that calls
  // process(): made there on the first call.
  std::unique_ptr<MfcRenderer> renderer;
  std::unique_ptr<PoseRefiner> refiner;
  std::vector<int> mesh_ids;              // per part
  std::vector<std::pair<int, int>> jobs;  // (part, view) searched this cycle
  std::vector<std::vector<Hit>> thread_hits;
  std::vector<uint64_t> thread_hypotheses;
  std::vector<int> thread_views;
  std::vector<Hit> hits;
  // Only the best hits a cycle fits (fitted_in) are used: each thread keeps a max-heap of its
  // best that many, and the worst of a full heap bounds every search (SharedCostBound).
  std::vector<std::vector<Candidate>> thread_best;
  std::atomic<uint64_t> shared_bound{SharedCostBound::kNone};
  struct Verified {
    Hit hit;
    double coverage = 0, combined = 0;
    RigidPose coarse, fitted;
    int view = 0;
    double fit_score = -1, fit_rank = -1;
    TemplateFitResult fit;     // the fit's measures at `fitted` (trace)
    bool skipped = false;      // not fitted: the deadline had passed
    bool below_floor = false;  // fitted reaching below the bin floor: dropped
    // The hypothesis becomes fit `f`, ranked `rank`.
    void take(const TemplateFitResult& f, double rank) {
      fitted = f.pose;
      view = f.view;
      fit_score = f.score;
      fit = f;
      fit_rank = rank;
    }
    // The hypothesis as a fit (pose, view and score as it stands), for TemplatePoseFit::compare.
    TemplateFitResult as_fit() const {
      TemplateFitResult f = fit;
      f.pose = fitted;
      f.view = view;
      f.score = fit_score;
      return f;
    }
  };
  // The hypotheses are fitted, checked and ranked without the edge offset correction; each pick
  // candidate's pose is then fitted once more with it (PipelineConfig::edge_offset_correction).
  // Why both: the correction removes a depth bias of ~2 mm for parts turned in the image, but
  // ranking with it broke more trials than it fixed, 20 to 11 over six sets (docs/pose.md, "Edge
  // offset profiles"), and the checks' thresholds were measured without it.
  TemplatePoseFit fitter;
  TemplatePoseFit final_fitter;
  bool fitter_prepared = false;  // the fitter indexes this cycle's edges (score_pose reuses them)
  // A fit of the hypothesis ranked `index` in its search scored as that rank is scored: with every
  // point of its view when the rescoring reaches it (PipelineConfig::rescore_hypotheses), else as
  // the fit's subsample scored it. The rescoring itself, and the new fits the floor starts and the
  // turned-over check make, go through here, so that they compare like for like.
  TemplateFitResult scored_like(int index, const TemplateDatabase& db, const TemplateFitResult& f) {
    if (index >= config.rescore_hypotheses) return f;
    return fitter.evaluate(db, f.view, f.pose, camera.camera, fit_workspaces[omp_get_thread_num()],
                           TemplatePoseFit::kAllPoints);
  }
  void prepare_fitter() {
    if (fitter_prepared) return;
    // Without polarity: the same edges, no shadow map (Mat headers, no allocation).
    fitter.prepare(config.edge_polarity ? edges : DepthEdges{edges.edges, edges.direction, {}});
    fitter_prepared = true;
  }
  std::vector<TemplatePoseFit::Workspace> fit_workspaces;  // per search thread
  std::vector<DistanceFitWorkspace> distance_workspaces;   // per search thread
  std::vector<LineSearchWorkspace> search_workspaces;      // per search thread
  std::vector<SearchResult> thread_results;                // per search thread, the last view's
  std::optional<CycleBudget> budget;                       // made once the thread count is known
  std::vector<Verified> verified;
  // Later search rounds (PipelineConfig::search_rounds): the query without the best candidates'
  // edges and its integral distance transform; `idt` stays the whole image's (score_pose uses it).
  cv::Mat1b erased;  // image size: the edges taken out
  LineFitResult round_query;
  IntegralDistanceTransform round_idt;

  // How a search is spread: the shipped settings (PipelineConfig) or escalation's wide ones.
  struct SearchSettings {
    int view_stride, query_guides, keep_per_view, keep_separation_px;
    double max_cost_px;
  };
  SearchSettings shipped_search() const {
    return {config.view_stride, config.query_guides, config.keep_per_view, config.keep_separation_px,
            config.max_cost_px};
  }
  SearchSettings escalation_search() const {
    return {1, config.escalate_query_guides, config.escalate_placements_per_view, config.escalate_separation_px,
            config.escalate_max_cost_px > 0 ? config.escalate_max_cost_px : config.max_cost_px};
  }

  // One cycle's settings and outcomes shared by the stages below.
  struct Cycle {
    int obj_id = 0;
    bool fdcm = true;
    size_t selected_parts = 0;
    Clock::time_point deadline, search_deadline;
    // The first few views and fits run even past the deadline, so that a late cycle still gives
    // picks (the first round; a later round only adds candidates).
    bool minimum_past_deadline = true;
    bool late = false;         // the search skipped views past its deadline
    bool fit_late = false;     // the fit skipped hypotheses past the deadline
    bool checks_late = false;  // the ranking skipped checks of leading hypotheses past the deadline
  };
  // The line search over every view of the selected parts into `hits`, best first, its bound
  // keeping the best `wanted` (fdcm_idt: FDCM's costs; null for the baselines).
  void search(Cycle& cycle, const LineSet& query, const IntegralDistanceTransform* fdcm_idt, size_t wanted,
              const SearchSettings& settings, PipelineResult& out);
  void verify(size_t count);  // appends the best `count` new distinct hits to `verified`
  // Hypotheses fitted in a cycle of `selected` part types (PipelineConfig::fit_candidates and
  // fit_candidates_per_type), and in a cycle of every part.
  size_t fitted_for(size_t selected) const {
    return static_cast<size_t>(config.fit_candidates) +
           static_cast<size_t>(config.fit_candidates_per_type) * (std::max<size_t>(selected, 1) - 1);
  }
  size_t fitted_in(const Cycle& cycle) const { return fitted_for(cycle.selected_parts); }
  size_t most_fitted() const { return fitted_for(parts.size()); }
  void fit(Cycle& cycle, size_t first, const IntegralDistanceTransform* fdcm_idt);
  void trace(size_t first, int round, PipelineResult& out) const;
  void sort_verified(size_t first);
  void rank(Cycle& cycle, size_t first);
  void check_spins(Cycle& cycle, size_t first, int pool);  // rank()'s spin check
  void query_without_best(int best);                       // into round_query
  // The cycle's stages in order (stage.hpp), made by the constructor.
  std::vector<std::unique_ptr<Stage>> stages;
  GraspVisibility grasp_visibility(int obj_id, const RigidPose& pose, const GraspFeature& feature) {
    return grasp_feature_visibility(edges, part_of(obj_id).db, camera.camera, pose, feature, config.fit_inlier_cost_px,
                                    own_edges);
  }
  // PoseCandidate::grasp_visibility at `pose`: the best of the part type's grasp features in the
  // last edges, 1 when it has none.
  double best_grasp_visibility(int obj_id, const RigidPose& pose) {
    bool any = false;
    double best = 0;
    for (const auto& [feature_obj_id, feature] : config.grasp_features)
      if (feature_obj_id == obj_id) {
        any = true;
        best = std::max(best, grasp_visibility(obj_id, pose, feature).visible);
      }
    return any ? best : 1.0;
  }
  // The pick candidates from `verified`, best first, at most max_candidates (candidates_stage.cpp).
  // The best-ranked other fitted hypothesis at the place of verified[index] whose image differs
  // from it (PoseCandidate::alternative_*), into `c`.
  void find_alternative(size_t index, PoseCandidate& c);
  void make_candidates(Clock::time_point deadline, PipelineResult& out);
  // The best refine_candidates candidates refined until the deadline (refinement_stage.cpp).
  void refine(Clock::time_point deadline, PipelineResult& out);
  // The renderer and refiner, made on first use in the calling thread (its GL context).
  void ensure_renderer();
  // A search after the first (a later round's or escalation's): its best `wanted` new hits
  // verified, fitted (traced as `round`) and ranked with the hypotheses so far. It has no "always
  // searched" views or fits, so the deadline only makes it add fewer.
  void add_search(const Cycle& cycle, const LineSet& query, const IntegralDistanceTransform& idt, size_t wanted,
                  const SearchSettings& settings, int round, PipelineResult& out);
  // The query at the search's resolution (PipelineConfig::search_downsample): `q` itself, or
  // reduced into search_lines / search_channels (each round's search needs them only until it ends).
  std::pair<const LineSet*, const cv::Mat1b*> search_query(const LineFitResult& q);

  Impl(const CameraConfig& cam, PipelineConfig cfg)
      : camera(cam),
        config(std::move(cfg)),
        extractor(cam.camera, cam.flashes, config.depth_edges),
        fitter(ranking_fit_params(config)),
        final_fitter(final_fit_params(config)) {}
  static TemplateFitParams ranking_fit_params(const PipelineConfig& c) {
    TemplateFitParams p;
    p.edge_offset_correction = false;
    p.score_gate_px = c.fit_score_gate_px;
    p.inlier_cost_px = c.fit_inlier_cost_px;
    return p;
  }
  // A polish of a converged fit: the correction moves points by at most ~0.4 px, so the final
  // gate from the start (no far edges to pair with) and a few steps; the score is not read.
  static TemplateFitParams final_fit_params(const PipelineConfig& c) {
    TemplateFitParams p = ranking_fit_params(c);
    p.edge_offset_correction = true;
    p.iterations = 3;
    p.initial_gate_px = p.final_gate_px;
    p.score_result = false;
    return p;
  }
};

}  // namespace mfcd::vision
