#include "vision/pipeline/bin_picking_pipeline.hpp"
#include "vision/pipeline/cycle_budget.hpp"
#include "vision/pipeline/part_model.hpp"
#include "vision/pipeline/pipeline_parameters.hpp"
#include "vision/pipeline/turn_checks.hpp"

#include "vision/dt3/directional_distance_transform.hpp"
#include "vision/idt3/integral_distance_transform.hpp"
#include "vision/lines/line_fitter.hpp"
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
#include <limits>
#include <optional>
#include <span>
#include <cmath>
#include <stdexcept>

namespace mfcd::vision {

using namespace detail;  // the pipeline's own parts: part_model.hpp, turn_checks.hpp

namespace {

using Clock = std::chrono::steady_clock;

struct Hit {
  int part = 0, view = 0, warp = 0;
  Candidate c;
  cv::Rect2d box;
};

// Best search cost first; ties broken by everything else, so that the order does not depend on
// which thread found what.
bool hit_order(const Hit& a, const Hit& b) {
  const uint64_t l = uint64_t(a.c.sum) * b.c.pixels, r = uint64_t(b.c.sum) * a.c.pixels;
  if (l != r) return l < r;
  if (a.part != b.part) return a.part < b.part;
  if (a.view != b.view) return a.view < b.view;
  if (a.warp != b.warp) return a.warp < b.warp;
  if (a.c.tx != b.c.tx) return a.c.tx < b.c.tx;
  return a.c.ty < b.c.ty;
}

double iou(const cv::Rect2d& a, const cv::Rect2d& b) {
  const double inter = (a & b).area();
  const double uni = a.area() + b.area() - inter;
  return uni > 0 ? inter / uni : 0;
}

// Weight of the image edges a template leaves unexplained: all of them unexplained costs as
// much as 3 px of mean chamfer distance.
constexpr double kUnexplainedPenaltyPx = 3.0;

// Hypotheses fitted even past the deadline (the best few by search cost): a late cycle still
// gives picks.
constexpr int kAlwaysFitted = 4;
// Views of each selected part searched even past the search's deadline (the first of the coarse
// pass, spread over the sphere).
constexpr size_t kAlwaysSearchedPerPart = 2;

// Largest change of the part's distance a hypothesis fit may make (fraction of the distance).
constexpr double kMaxFitDepthChange = 0.08;

// One view constrains depth weakly; a fit that walks far along the line of sight from the
// distance the image scale gave (fit_distance) has slid onto other edges.
bool moved_too_far_in_depth(const TemplateDatabase& db, const RigidPose& coarse, const RigidPose& fitted) {
  const double z0 = cv::norm(coarse.R * db.center_mm + coarse.t_mm);
  const double z1 = cv::norm(fitted.R * db.center_mm + fitted.t_mm);
  return std::abs(z1 - z0) > kMaxFitDepthChange * z0;
}

// Floor starts (PipelineConfig::floor_starts): hypotheses whose lowest point lies up to this high
// above the floor are fitted again from the floor, and the floor-start fit is kept when it scores
// at least this share of the free fit: a prior that a part low in the bin rests on the floor,
// which a single view cannot tell from a part a few millimetres nearer. Measured on three dev sets
// (mfc-sim seeds 7, 13, 19; 283 trials, floor at 300 mm) and the bench set (119 trials): 85 and 32
// failures without, 81 and 30 with the 6 best (height 30 mm, share 0.8). Other settings are in
// docs/pose.md (share 1.0, the better of the two fits: 1 and 2 failures more).
constexpr double kFloorStartHeightMm = 30;
constexpr double kFloorStartMinScoreRatio = 0.8;

// Search rounds (PipelineConfig::search_rounds): a later round takes out the image edges within
// this many pixels of the best candidates' points.
constexpr int kRoundErasePx = 2;
// Candidates whose search boxes overlap by more than this (intersection over union) are one part.
constexpr double kCandidateOverlap = 0.3;

// Escalation's wide search (PipelineConfig::escalate_below): every view, and per view its best
// two placements at least this far apart (full-resolution px), so that a part whose view matches
// clutter better still gets a placement of its own.
constexpr int kEscalationPlacementsPerView = 2;
constexpr int kEscalationSeparationPx = 40;

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

}  // namespace

struct BinPickingPipeline::Impl {
  CameraConfig camera;
  PipelineConfig config;
  LineFitter line_fitter;  // default LineFitParams, oriented as the templates' lines
  LineFitResult lines;  // this cycle's query lines (buffers reused)
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
  cv::Mat1b own_edges;  // grasp visibility: the pixels a candidate's own points explain (kept zero between uses)
  Dt3Params search_dt3;      // dt3_params in reduced pixels
  cv::Mat1b search_channels;  // the line fitter's channel map, reduced
  LineSet search_lines;      // the query lines, reduced
  DirectionalDistanceTransform dt3;
  IntegralDistanceTransform idt;
  ChamferCosts chamfer;  // baselines only
  // Refinement renders the model, so it needs a GL context bound to the thread that calls
  // process(): made there on the first call.
  std::unique_ptr<MfcRenderer> renderer;
  std::unique_ptr<PoseRefiner> refiner;
  std::vector<int> mesh_ids;  // per part
  std::vector<std::pair<int, int>> jobs;           // (part, view) searched this cycle
  std::vector<std::vector<Hit>> thread_hits;
  std::vector<uint64_t> thread_hypotheses;
  std::vector<int> thread_views;
  std::vector<Hit> hits;
  // Only the best fit_candidates hits of a cycle are used: each thread keeps a max-heap of its
  // best that many, and the worst of a full heap bounds every search (SharedCostBound).
  std::vector<std::vector<Candidate>> thread_best;
  std::atomic<uint64_t> shared_bound{SharedCostBound::kNone};
  struct Verified {
    Hit hit;
    double coverage = 0, combined = 0;
    RigidPose coarse, fitted;
    int view = 0;
    double fit_score = -1, fit_rank = -1;
    TemplateFitResult fit;  // the fit's measures at `fitted` (trace)
    bool skipped = false;  // not fitted: the deadline had passed
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
  std::vector<DistanceFitWorkspace> distance_workspaces;  // per search thread
  std::vector<LineSearchWorkspace> search_workspaces;     // per search thread
  std::vector<SearchResult> thread_results;               // per search thread, the last view's
  std::optional<CycleBudget> budget;  // made once the thread count is known
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
    return {1, config.escalate_query_guides, kEscalationPlacementsPerView, kEscalationSeparationPx,
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
    bool late = false;      // the search skipped views past its deadline
    bool fit_late = false;  // the fit skipped hypotheses past the deadline
  };
  // The line search over every view of the selected parts into `hits`, best first, its bound
  // keeping the best `wanted` (fdcm_idt: FDCM's costs; null for the baselines).
  void search(Cycle& cycle, const LineSet& query, const IntegralDistanceTransform* fdcm_idt, size_t wanted,
              const SearchSettings& settings, PipelineResult& out);
  void verify(size_t count);  // appends the best `count` new distinct hits to `verified`
  void fit(Cycle& cycle, size_t first, const IntegralDistanceTransform* fdcm_idt);
  void trace(size_t first, int round, PipelineResult& out) const;
  void sort_verified(size_t first);
  void rank(const Cycle& cycle, size_t first);
  void check_spins(const Cycle& cycle, size_t first, int pool);  // rank()'s spin check
  void query_without_best(int best);  // into round_query
  // A search after the first (a later round's or escalation's): its best `wanted` new hits
  // verified, fitted (traced as `round`) and ranked with the hypotheses so far. It has no "always
  // searched" views or fits, so the deadline only makes it add fewer.
  void add_search(const Cycle& cycle, const LineSet& query, const IntegralDistanceTransform& idt, size_t wanted,
                  const SearchSettings& settings, int round, PipelineResult& out);
  // The query at the search's resolution (PipelineConfig::search_downsample): `q` itself, or
  // reduced into search_lines / search_channels (each round's search needs them only until it ends).
  std::pair<const LineSet*, const cv::Mat1b*> search_query(const LineFitResult& q);

  Impl(const CameraConfig& cam, PipelineConfig cfg)
      : camera(cam), config(std::move(cfg)), extractor(cam.camera, cam.flashes, config.depth_edges),
        fitter(ranking_fit_params(config)), final_fitter(final_fit_params(config)) {}
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

namespace {

// The fraction of image edge pixels inside the placed template's outline (convex hull of its
// edge points) that lie within 2 px of a template edge point. Scratch: the fit's per-thread
// workspace (its coverage buffers, grown for every view at configure).
double explained_fraction(const TemplateView& view, const Warp& warp, int tx, int ty, const cv::Mat1b& edges,
                          TemplatePoseFit::Workspace& ws) {
  const cv::Matx22d A = warp.matrix();
  const cv::Rect image(cv::Point(0, 0), edges.size());
  ws.placed.clear();
  for (const auto& p : view.points) {
    const cv::Vec2d q = A * cv::Vec2d(p.pixel.x, p.pixel.y);
    const cv::Point r(cvRound(q[0] + tx), cvRound(q[1] + ty));
    if (image.contains(r)) ws.placed.push_back(r);
  }
  return explained_edge_fraction(edges, ws.placed, ws.region, ws.explained);
}

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

// The fitted view's edge points at the fitted distance (a view's point count scales with 1 / distance).
double view_points(const TemplateFitResult& f, const TemplateDatabase& db) {
  const double z = cv::norm(f.pose.R * db.center_mm + f.pose.t_mm);
  return static_cast<double>(db.views[static_cast<size_t>(f.view)].points.size()) * db.distance_mm / z;
}

// The rank of a fitted hypothesis: its fit score, less a penalty for the image edges inside its
// outline it leaves unexplained, plus the evidence of the edge points it found (PipelineConfig::evidence_weight).
// All of them unexplained costs PipelineConfig::unexplained_weight (0.3), about the score a correct
// fit of a part in a full bin reaches (measured on mfc-sim bins: correct picks score 0.1-0.5).
double fitted_rank(const TemplateFitResult& f, const TemplateDatabase& db, const PipelineConfig& c) {
  const double n = view_points(f, db);
  // n x inlier fraction: the points found, not those the view has (PipelineConfig::evidence_weight).
  return f.score - c.unexplained_weight * (1.0 - f.coverage) +
         c.evidence_weight * std::log(std::max(n * f.inlier_fraction, 1.0) / 300.0);
}

// The search ran at the templates' own distance, but parts in a bin lie nearer (stacked, or
// their centre above the floor): their images are larger by distance / actual distance. Around
// a match, scale (the distance), in-plane angle (one channel step either way) and translation
// (3 px) are searched locally with FDCM, so the coarse pose gets its depth from the image.
// `idt` is the search's, at 1/down of the image's resolution (PipelineConfig::search_downsample:
// the 3 px are the search's pixels; a full-resolution IDT3 here measured worse, docs/fdcm.md); `full`
// and the returned cost are in full-resolution pixels.
double fit_distance(const LineSet& lines, const IntegralDistanceTransform& idt, int down, TemplatePlacement& full,
                    DistanceFitWorkspace& ws) {
  const FdcmMatcher matcher(idt);
  TemplatePlacement pl = full;
  pl.scale /= down;
  pl.origin_px *= 1.0 / down;
  const double step = OrientationChannels(lines.q, lines.oriented).step();
  double best_cost = std::numeric_limits<double>::infinity();
  TemplatePlacement best = pl;
  uint64_t segments = 0;
  // Scales in 2 % steps, then the 1 % steps either side of the best (the cost is smooth in
  // scale at this resolution): 14 template warps per angle instead of 23 for every 1 % step.
  int best_si = 0;
  auto try_scale = [&](int si) {
    const double scale = pl.scale * std::pow(1.01, si);
    for (int ai = -1; ai <= 1; ++ai) {
      orientTemplate(lines, 0, Warp{pl.angle_rad + ai * step, scale, 1.0}, ws.warped, ws.scratch);
      const OrientedTemplate& t = ws.warped;
      if (t.pixels <= 0) continue;
      for (int dy = -3; dy <= 3; ++dy)
        for (int dx = -3; dx <= 3; ++dx) {
          const int tx = static_cast<int>(pl.origin_px.x) + dx, ty = static_cast<int>(pl.origin_px.y) + dy;
          if (tx < t.txMin() || tx > t.txMax(idt.width()) || ty < t.tyMin() || ty > t.tyMax(idt.height())) continue;
          const uint32_t stop = std::isfinite(best_cost)
                                    ? static_cast<uint32_t>(best_cost * kCostScale * t.pixels) + 1
                                    : std::numeric_limits<uint32_t>::max();
          const uint32_t sum = matcher.evaluateAt(t, tx, ty, stop, segments);
          const double cost = double(sum) / (double(kCostScale) * t.pixels);
          if (cost < best_cost) {
            best_cost = cost;
            best.angle_rad = pl.angle_rad + ai * step;
            best.scale = scale;
            best.origin_px = cv::Point2d(tx, ty);
            best_si = si;
          }
        }
    }
  };
  for (int si = -8; si <= 14; si += 2) try_scale(si);
  const int centre = best_si;
  if (centre > -8) try_scale(centre - 1);
  if (centre < 14) try_scale(centre + 1);
  full = best;
  full.scale *= down;
  full.origin_px *= double(down);
  return best_cost * down;
}

// The table's ranges (pipeline_parameters.hpp), checked before anything is made from them (the
// fitters would refuse bad gates in their own words, naming TemplateFitParams fields).
PipelineConfig checked_parameters(PipelineConfig c) {
  try {
    validate_parameters(c);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(e.what());
  }
  return c;
}

}  // namespace

BinPickingPipeline::BinPickingPipeline(const CameraConfig& camera, PipelineConfig config)
    : impl_(std::make_unique<Impl>(camera, checked_parameters(std::move(config)))) {
  Impl& m = *impl_;
  if (m.config.template_files.empty()) throw std::runtime_error("pipeline: no template files configured");
  for (const auto& file : m.config.template_files) {
    PartModel part = load_part_model(file, camera, m.config);
    for (const auto& other : m.parts)
      if (other.db.obj_id == part.db.obj_id)
        throw std::runtime_error(part.file + ": obj_id " + std::to_string(part.db.obj_id) + " is also used by " +
                                 other.file);
    if (m.parts.empty()) {  // the first part decides the search's channels; every other must agree
      m.dt3_params.q = part.db.q;
      m.dt3_params.oriented = part.db.oriented;
      LineFitParams query = m.line_fitter.params();
      query.q = part.db.oriented ? part.db.q / 2 : part.db.q;
      query.oriented = part.db.oriented;
      m.line_fitter = LineFitter(query);
    }
    if (part.db.q != m.dt3_params.q || part.db.oriented != m.dt3_params.oriented)
      throw std::runtime_error(part.file + ": templates have q = " + std::to_string(part.db.q) +
                               (part.db.oriented ? " oriented" : "") + ", the pipeline " +
                               std::to_string(m.dt3_params.q) + (m.dt3_params.oriented ? " oriented" : ""));
    m.parts.push_back(std::move(part));
  }
  try {
    m.config.floor.validate();
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(std::string("pipeline: ") + e.what());
  }
  for (const auto& [obj_id, feature] : m.config.grasp_features) {
    bool loaded = false;
    for (const auto& p : m.parts) loaded = loaded || p.db.obj_id == obj_id;
    if (!loaded) throw std::runtime_error("pipeline: a grasp feature names obj_id " + std::to_string(obj_id) +
                                          ", which no template file defines");
    const std::string why = feature.validate();
    if (!why.empty()) throw std::runtime_error("pipeline: grasp feature of obj_id " + std::to_string(obj_id) + ": " + why);
  }
  m.dt3_params.polarityPenalty = m.config.search_polarity_penalty_px;
  m.search_dt3 = m.dt3_params;
  m.search_dt3.lambda /= m.config.search_downsample;
  m.search_dt3.maxCost /= m.config.search_downsample;
  m.search_dt3.polarityPenalty /= m.config.search_downsample;
  const int threads = m.config.threads > 0 ? m.config.threads : omp_get_max_threads();
  m.thread_hits.resize(static_cast<size_t>(threads));
  m.thread_hypotheses.resize(static_cast<size_t>(threads));
  m.thread_views.resize(static_cast<size_t>(threads));
  for (auto& h : m.thread_hits) h.reserve(4096);
  m.thread_best.resize(static_cast<size_t>(threads));
  for (auto& h : m.thread_best)
    h.reserve(std::max<size_t>({static_cast<size_t>(std::max(m.config.fit_candidates, m.config.round_hypotheses) *
                                                    m.config.keep_per_view),
                                static_cast<size_t>(m.config.escalate_hypotheses * kEscalationPlacementsPerView),
                                m.config.coarse_seeds * m.parts.size()}) +
              1);
  m.hits.reserve(4096);
  m.verified.reserve(static_cast<size_t>(m.config.fit_candidates) +
                     static_cast<size_t>(m.config.search_rounds - 1) * static_cast<size_t>(m.config.round_hypotheses) +
                     (m.config.escalate_below > 0 ? static_cast<size_t>(m.config.escalate_hypotheses) : 0));
  m.fit_workspaces.resize(static_cast<size_t>(threads));
  m.distance_workspaces.resize(static_cast<size_t>(threads));
  // Every per-thread buffer of the fits grown here for every view (a thread meets views in any
  // order), so that the frame path never grows them. fit_distance digitises a hit's view at up to
  // 1.01^14 its scale, at the search's reduction.
  constexpr double kFitStretch = 1.2;
  for (const auto& part : m.parts) {
    for (auto& ws : m.fit_workspaces) m.fitter.reserve(part.db, camera.camera.image_size, ws);
    double stretch = 0;
    for (const Warp& w : part.warps) stretch = std::max(stretch, w.scale * std::max(1.0, w.aspect));
    for (auto& ws : m.distance_workspaces)
      for (const auto& view : part.db.views)
        reserveOrientedTemplate(view.lines, stretch * kFitStretch / m.config.search_downsample, ws.warped, ws.scratch);
  }
  m.search_workspaces.resize(static_cast<size_t>(threads));
  m.thread_results.resize(static_cast<size_t>(threads));
  size_t views = 0;
  for (const auto& part : m.parts) views += part.db.views.size();
  m.jobs.reserve(views);
  m.budget.emplace(m.config.fit_candidates, threads);
  m.erased = cv::Mat1b::zeros(camera.camera.image_size);
}

BinPickingPipeline::~BinPickingPipeline() = default;

std::vector<std::pair<int, std::string>> BinPickingPipeline::parts() const {
  std::vector<std::pair<int, std::string>> out;
  for (const auto& p : impl_->parts) out.emplace_back(p.db.obj_id, p.db.part_name);
  return out;
}
const CameraConfig& BinPickingPipeline::camera() const { return impl_->camera; }
const DepthEdges& BinPickingPipeline::last_edges() const { return impl_->edges; }

// Coarse to fine, every part at once. The coarse stage: every `view_stride`-th view of every
// selected part, in four passes (every 4th of them first, then those halfway between, then the
// rest: views are numbered along a spiral on the sphere, so each pass is spread over it). A
// search the deadline cuts short has still looked at every part from all round, and the
// hypothesis fit moves between neighbouring views.
void BinPickingPipeline::Impl::search(Cycle& cycle, const LineSet& query, const IntegralDistanceTransform* fdcm_idt,
                                      size_t wanted, const SearchSettings& settings, PipelineResult& out) {
  Impl& m = *this;
  const int down = m.config.search_downsample;
  m.jobs.clear();
  const int stride = settings.view_stride;
  static constexpr int kPassOf[4] = {0, 2, 1, 3};  // pass of (view / stride) % 4
  for (auto& part : m.parts) std::fill(part.searched.begin(), part.searched.end(), 0);
  for (int pass = 0; pass < 4; ++pass)
    for (int v = 0;; v += stride) {
      bool any = false;
      for (int p = 0; p < static_cast<int>(m.parts.size()); ++p) {
        if (cycle.obj_id != 0 && m.parts[p].db.obj_id != cycle.obj_id) continue;
        if (v >= static_cast<int>(m.parts[p].db.views.size())) continue;
        any = true;
        if (kPassOf[(v / stride) % 4] == pass) m.jobs.emplace_back(p, v), m.parts[p].searched[v] = 1;
      }
      if (!any) break;
    }
  std::optional<FdcmMatcher> matcher;      // FDCM: over the round's integral distance transform
  std::optional<ChamferMatcher> baseline;  // built from the baseline costs only when they exist
  if (cycle.fdcm)
    matcher.emplace(*fdcm_idt);
  else
    baseline.emplace(m.chamfer, m.config.cost == PipelineConfig::Cost::cm ? ChamferMatcher::Kind::Chamfer
                                                                          : ChamferMatcher::Kind::OrientedChamfer);
  LineSearchParams lp;
  // Per view only its best placement is kept (Best mode): its bound tightens as the search
  // improves, far cheaper than collecting every placement under the threshold. Several instances
  // of a part still come out, through different (neighbouring) views, after NMS.
  lp.mode = SearchMode::Best;
  lp.threshold = settings.max_cost_px / down;
  lp.templateLines = m.config.template_guides;
  lp.queryLines = settings.query_guides;
  lp.minOverlap = m.config.min_guide_overlap;
  lp.slideStep = m.config.slide_step;
  lp.keep = settings.keep_per_view;
  lp.separationPx = std::max(1, settings.keep_separation_px / down);
  m.shared_bound.store(SharedCostBound::kNone);
  if (m.config.share_search_bound) lp.sharedBound = &m.shared_bound;
  const size_t useful = std::max(wanted * static_cast<size_t>(settings.keep_per_view),
                                 static_cast<size_t>(m.config.coarse_seeds) * cycle.selected_parts);
  for (auto& h : m.thread_best) h.clear();
  std::atomic<bool> late{false};
  for (auto& h : m.thread_hits) h.clear();
  std::fill(m.thread_hypotheses.begin(), m.thread_hypotheses.end(), 0);
  std::fill(m.thread_views.begin(), m.thread_views.end(), 0);
  const int threads = static_cast<int>(m.thread_hits.size());
  auto search_jobs = [&](size_t first) {
#pragma omp parallel for schedule(dynamic, 4) num_threads(threads)
    for (int j = static_cast<int>(first); j < static_cast<int>(m.jobs.size()); ++j) {
      // The first few views of every part are searched even when late (the jobs interleave the
      // parts), so that a late cycle still has hypotheses to give its best-so-far picks from.
      const bool always =
          cycle.minimum_past_deadline && static_cast<size_t>(j) < kAlwaysSearchedPerPart * cycle.selected_parts;
      if (!always && late.load(std::memory_order_relaxed)) continue;
      if (!always && Clock::now() > cycle.search_deadline) {
        late = true;
        continue;
      }
      const auto [p, v] = m.jobs[j];
      const auto& list = m.parts[p].oriented[v];
      const int me = omp_get_thread_num();
      SearchResult& r = m.thread_results[me];
      if (cycle.fdcm)
        lineSearch(*matcher, list, query.lines, lp, m.search_workspaces[me], r);
      else
        r = lineSearch(*baseline, list, query.lines, lp);  // the baselines are evaluation tools
      auto& mine = m.thread_hits[me];
      m.thread_hypotheses[me] += r.stats.evaluated;
      ++m.thread_views[me];
      auto& best = m.thread_best[me];
      for (const Candidate& c : r.candidates) {
        const cv::Rect2d box = placedBox(list[c.oriented], c);
        mine.push_back({p, v, c.oriented, c, cv::Rect2d(box.x * down, box.y * down, box.width * down, box.height * down)});
        best.push_back(c);
        std::push_heap(best.begin(), best.end(), better);  // worst on top
        if (best.size() > useful) {
          std::pop_heap(best.begin(), best.end(), better);
          best.pop_back();
        }
        if (best.size() == useful)
          SharedCostBound::lower(m.shared_bound, best.front().sum, static_cast<uint32_t>(best.front().pixels));
      }
    }
  };
  // Every thread's hits so far in one list, best first (hit_order: independent of the threads).
  auto gather_hits = [&] {
    m.hits.clear();
    for (const auto& h : m.thread_hits) m.hits.insert(m.hits.end(), h.begin(), h.end());
    std::sort(m.hits.begin(), m.hits.end(), hit_order);
  };
  search_jobs(0);
  // The fine stage: the views around the best coarse_seeds x (parts searched) coarse hits, the
  // best hit's first, so that a deadline cuts the least promising. (These seeds are always among
  // the hits the shared bound keeps: it keeps at least that many.)
  if (stride > 1 && m.config.coarse_seeds > 0 && !late.load()) {
    const size_t coarse_jobs = m.jobs.size();
    gather_hits();
    const size_t seeds = std::min(m.hits.size(), static_cast<size_t>(m.config.coarse_seeds) * cycle.selected_parts);
    for (size_t i = 0; i < seeds; ++i) {
      const Hit& h = m.hits[i];
      PartModel& part = m.parts[h.part];
      for (int u : part.neighbours[h.view])
        if (!part.searched[u]) part.searched[u] = 1, m.jobs.emplace_back(h.part, u);
    }
    search_jobs(coarse_jobs);
  }
  cycle.late = late.load();
  for (int k = 0; k < threads; ++k) out.hypotheses += m.thread_hypotheses[k], out.views_searched += m.thread_views[k];
  gather_hits();
}

// Verification. Chamfer matching only asks whether the template's edges are in the image, so a
// view with fewer edges (the plain back of a part) matches wherever the detailed front does.
// The distinct best hits are re-ranked by also asking the converse: which fraction of the
// image's edges inside the placed outline the template explains (within 2 px). A hit that repeats
// one verified before (same view, same place: an earlier round's) is not taken again.
void BinPickingPipeline::Impl::verify(size_t count) {
  Impl& m = *this;
  const int down = m.config.search_downsample;
  const size_t first = m.verified.size();
  for (const Hit& h : m.hits) {
    if (m.verified.size() - first >= count) break;
    bool duplicate = false;
    for (const auto& k : m.verified) duplicate = duplicate || (k.hit.part == h.part && iou(k.hit.box, h.box) > 0.8 &&
                                                               k.hit.view == h.view);
    if (duplicate) continue;
    Verified v;
    v.hit = h;
    m.verified.push_back(v);
  }
  // The coverages are independent of each other: shared out among the threads.
  const int threads = static_cast<int>(m.thread_hits.size());
#pragma omp parallel for schedule(dynamic, 2) num_threads(threads)
  for (int i = static_cast<int>(first); i < static_cast<int>(m.verified.size()); ++i) {
    Verified& v = m.verified[i];
    const Hit& h = v.hit;
    const PartModel& part = m.parts[h.part];
    v.coverage = explained_fraction(part.db.views[h.view], part.warps[h.warp], h.c.tx * down, h.c.ty * down,
                                    m.edges.edges, m.fit_workspaces[omp_get_thread_num()]);
    v.combined = h.c.cost() * down + kUnexplainedPenaltyPx * (1.0 - v.coverage);
  }
}

// Each hypothesis from `first` on: local fit of distance, angle and translation (FDCM), its
// coarse 3-D pose, then the 6-DoF fit with the template's model points (TemplatePoseFit): the
// sampled views are up to ~6 degrees off any real pose, and only after this fit does the truth
// score clearly better than clutter. Hypotheses are then ranked by the fitted score.
void BinPickingPipeline::Impl::fit(Cycle& cycle, size_t first, const IntegralDistanceTransform* fdcm_idt) {
  Impl& m = *this;
  const int down = m.config.search_downsample;
  const int threads = static_cast<int>(m.thread_hits.size());
  std::atomic<bool> fit_late{false};
  const BinFloor& floor = m.config.floor;
  const int begin = static_cast<int>(first);
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
  for (int i = begin; i < static_cast<int>(m.verified.size()); ++i) {
    Verified& v = m.verified[i];
    v.fit_score = -1;
    // Past the deadline only the first few (the best by search cost) are still fitted, so that a
    // late cycle still gives its best-so-far picks.
    const bool always = cycle.minimum_past_deadline && i - begin < kAlwaysFitted;
    v.skipped = !always && (fit_late.load(std::memory_order_relaxed) || Clock::now() > cycle.deadline);
    if (v.skipped) {
      fit_late = true;
      continue;
    }
    const Hit& h = v.hit;
    const PartModel& part = m.parts[h.part];
    const Warp& w = part.warps[h.warp];
    TemplatePlacement pl;
    pl.view = h.view;
    pl.angle_rad = w.angle;
    pl.scale = w.scale;
    pl.origin_px = cv::Point2d(h.c.tx * down, h.c.ty * down);
    if (cycle.fdcm)
      fit_distance(part.db.views[h.view].lines, *fdcm_idt, down, pl, m.distance_workspaces[omp_get_thread_num()]);
    v.coarse = coarse_pose(part.db, pl, m.camera.camera);
    v.view = h.view;
    if (cycle.fdcm && m.config.fit_hypotheses) {
      const TemplateFitResult f =
          m.fitter.fit(part.db, h.view, v.coarse, m.camera.camera, m.fit_workspaces[omp_get_thread_num()]);
      if (moved_too_far_in_depth(part.db, v.coarse, f.pose)) {
        // Refused: the hypothesis keeps its unfitted coarse pose, ranked last, and like every
        // unfitted pose it goes onto the floor when it reaches below.
        v.fitted = floor.onto_if_below(part.db.mesh, v.coarse, part.db.center_mm);
        v.fit_score = 0;
        v.fit_rank = -1;
        continue;
      }
      // No part can lie there. About half of the fitted hypotheses of a full bin do (dev set 7:
      // 555 of 1000); fitting them again from the floor cost ~5 ms a cycle for no measured gain.
      v.below_floor = floor.below(part.db.mesh, f.pose);
      if (v.below_floor) continue;
      v.take(f, fitted_rank(f, part.db, m.config));
    } else {
      // The search's distance is one of a few guesses: a pose below the floor goes onto it.
      v.fitted = floor.onto_if_below(part.db.mesh, v.coarse, part.db.center_mm);
    }
  }
  // Hypotheses the deadline left unfitted are dropped (the best-so-far result is flagged degraded),
  // and so are fitted ones no part could take (below the floor).
  m.verified.erase(std::remove_if(m.verified.begin() + begin, m.verified.end(),
                                  [](const Verified& v) { return v.skipped || v.below_floor; }),
                   m.verified.end());
  cycle.fit_late = cycle.fit_late || fit_late.load();
}

void BinPickingPipeline::Impl::trace(size_t first, int round, PipelineResult& out) const {
  const Impl& m = *this;
  const int down = m.config.search_downsample;
  for (size_t i = first; i < m.verified.size(); ++i) {
    const Verified& v = m.verified[i];
    HypothesisTrace h;
    h.obj_id = m.parts[v.hit.part].db.obj_id;
    h.round = round;
    h.search_view = v.hit.view;
    h.fitted_view = v.view;
    h.search_cost_px = v.hit.c.cost() * down;
    h.coverage = v.coverage;
    h.R_coarse = v.coarse.R;
    h.t_coarse_mm = v.coarse.t_mm;
    h.R_fitted = v.fitted.R;
    h.t_fitted_mm = v.fitted.t_mm;
    h.fit_rank = v.fit_rank;
    h.fit_score = v.fit.score;
    h.fit_coverage = v.fit.coverage;
    h.inlier_fraction = v.fit.inlier_fraction;
    h.mean_cost_px = v.fit.mean_cost_px;
    if (v.fit.view >= 0) h.view_points = view_points(v.fit, m.parts[v.hit.part].db);
    out.trace.push_back(h);
  }
}

// Best first from `first` on: by the fitted rank, or without the fit (the baselines, search
// only) by the search's combined cost.
void BinPickingPipeline::Impl::sort_verified(size_t first) {
  if (config.cost == PipelineConfig::Cost::fdcm && config.fit_hypotheses)
    stable_sort_in_place(verified, [](const Verified& a, const Verified& b) { return a.fit_rank > b.fit_rank; }, first);
  else
    stable_sort_in_place(verified, [](const Verified& a, const Verified& b) { return a.combined < b.combined; }, first);
}

// Ranks the hypotheses from `first` on, and checks the best few of them against the floor and
// turned over.
void BinPickingPipeline::Impl::rank(const Cycle& cycle, size_t first) {
  Impl& m = *this;
  sort_verified(first);
  if (!cycle.fdcm || !m.config.fit_hypotheses) return;
  const int threads = static_cast<int>(m.thread_hits.size());
  const BinFloor& floor = m.config.floor;
  const int begin = static_cast<int>(first);
  const int count = static_cast<int>(m.verified.size()) - begin;
  // The checks below fit hypothesis i again from another start (on the calling OpenMP thread's
  // workspace), scored as its rank was.
  auto fit_from = [&](int i, const TemplateDatabase& db, RigidPose start) {
    const int view = TemplatePoseFit::nearest_view(db, m.camera.camera, start);
    return m.scored_like(i - begin, db,
                         m.fitter.fit(db, view, start, m.camera.camera, m.fit_workspaces[omp_get_thread_num()]));
  };
  // Each check runs on the best `n` hypotheses that have a fit, shared out among the threads,
  // until the deadline; then the hypotheses are ordered by their ranks again.
  auto check_leaders = [&](int n, auto&& check) {
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
    for (int i = begin; i < begin + n; ++i) {
      Verified& v = m.verified[i];
      if (v.fit_score <= 0 || Clock::now() > cycle.deadline) continue;
      check(i, v, m.parts[v.hit.part]);
    }
    if (n > 0) sort_verified(first);
  };
  // Rescoring: the fit scores a pose with at most TemplateFitParams::max_points of its view's
  // points (160 of up to ~1100), so two poses a few hundredths apart are ordered partly by which
  // points the subsample kept. The best few are scored again with every point before the checks
  // below and the choice of the cycle's picks (PipelineConfig::rescore_hypotheses).
  const int rescored = std::min(m.config.rescore_hypotheses, count);
  check_leaders(rescored, [&](int i, Verified& v, const PartModel& part) {
    const TemplateFitResult f = m.scored_like(i - begin, part.db, v.fit);
    v.take(f, fitted_rank(f, part.db, m.config));
  });
  // Floor starts: one view measures a part's distance poorly, and the fit converges to the
  // depth nearest its start. Parts low in the bin mostly rest on its floor, so the best few
  // hypotheses whose lowest point hovers above the floor are fitted again from the pose slid
  // down onto it (the fit stays free to leave it).
  check_leaders(floor.known() ? std::min(m.config.floor_starts, count) : 0,
                [&](int i, Verified& v, const PartModel& part) {
    const double height = -floor.reach_below(part.db.mesh, v.fitted);
    if (height <= floor.tolerance_mm || height > kFloorStartHeightMm) return;
    const TemplateFitResult f = fit_from(i, part.db, floor.onto(part.db.mesh, v.fitted, part.db.center_mm));
    if (f.score < kFloorStartMinScoreRatio * v.fit_score || floor.below(part.db.mesh, f.pose) ||
        moved_too_far_in_depth(part.db, v.coarse, f.pose))
      return;
    v.take(f, fitted_rank(f, part.db, m.config));
  });
  // Depth starts (PipelineConfig::depth_starts): the fit settles on the depth nearest its start,
  // so the best few are fitted again from a little further and a little nearer; a fit that ranks
  // higher replaces theirs unless it reaches below the floor or has left its search hit's depth.
  check_leaders(std::min(m.config.depth_starts, count), [&](int i, Verified& v, const PartModel& part) {
    // Further first, then nearer from whichever fit is best by then.
    for (const double delta : {m.config.depth_start_mm, -m.config.depth_start_mm}) {
      RigidPose start = v.fitted;
      const cv::Vec3d centre = start.R * part.db.center_mm + start.t_mm;
      start.t_mm += centre * (delta / cv::norm(centre));
      const TemplateFitResult f = fit_from(i, part.db, start);
      if (floor.below(part.db.mesh, f.pose) || moved_too_far_in_depth(part.db, v.coarse, f.pose)) continue;
      const double rank = fitted_rank(f, part.db, m.config);
      if (rank > v.fit_rank) v.take(f, rank);
    }
  });
  // Turned-over check of the best few: a part that is symmetric but for a small feature (the
  // breaker's toggle) fits as well turned by 180 degrees about an axis; the edges can only tell
  // the two apart where they differ (TemplatePoseFit::compare).
  check_leaders(std::min(m.config.flip_checks, count), [&](int i, Verified& v, const PartModel& part) {
    auto& ws = m.fit_workspaces[omp_get_thread_num()];
    TemplateFitResult current = v.as_fit();
    for (const PartModel::Turn& turn : part.flips) {
      const cv::Matx33d& S = turn.S;
      RigidPose turned;
      turned.R = current.pose.R * S;
      turned.t_mm = current.pose.t_mm + current.pose.R * (turn.pivot_mm - S * turn.pivot_mm);
      const TemplateFitResult f = fit_from(i, part.db, turned);
      if (moved_too_far_in_depth(part.db, v.coarse, f.pose) || f.score < kFlipMinScoreRatio * current.score ||
          floor.below(part.db.mesh, f.pose))
        continue;
      if (turn.by_rank) {
        if (v.fit_rank < kPlateTurnMinRank || fitted_rank(f, part.db, m.config) <= v.fit_rank) continue;
      } else {
        const bool feature = !turn.differs.empty();
        const TemplatePoseFit::Difference d =
            m.fitter.compare(part.db, current, f, m.camera.camera, ws,
                             feature ? &turn.differs[static_cast<size_t>(current.view)] : nullptr,
                             feature ? &turn.differs[static_cast<size_t>(f.view)] : nullptr);
        if (!turn_is_better(d)) continue;
      }
      current = f;
      // The turned pose replaces the fit, but never lowers the rank the hypothesis was sorted by.
      v.take(f, std::max(v.fit_rank, fitted_rank(f, part.db, m.config)));
    }
  });
  check_spins(cycle, first, rescored);
}

void BinPickingPipeline::Impl::check_spins(const Cycle& cycle, size_t first, int pool) {
  Impl& m = *this;
  const int begin = static_cast<int>(first);
  const int leaders = std::min(kSpinCheckLeaders, pool);
  // Serial: a leader reads the lower hypotheses it is compared with, and few leaders qualify.
  auto& ws = m.fit_workspaces[0];
  auto normal = [](const RigidPose& p) { return cv::Vec3d(p.R(0, 2), p.R(1, 2), p.R(2, 2)); };
  for (int i = begin; i < begin + leaders; ++i) {
    Verified& v = m.verified[i];
    if (v.fit_score <= 0 || Clock::now() > cycle.deadline) continue;
    const PartModel& part = m.parts[v.hit.part];
    const PartSymmetry& sym = part.db.symmetry;
    if (sym.kind != PartSymmetry::Kind::discrete_z || sym.order != 2) continue;
    TemplateFitResult current = v.as_fit();
    const cv::Vec3d centre = current.pose.R * part.db.center_mm + current.pose.t_mm;
    const cv::Vec3d n = normal(current.pose);
    const double tilt = degrees(std::acos(std::min(1.0, std::abs(n.dot(centre / cv::norm(centre))))));
    if (tilt < kSpinCheckMinTiltDeg) continue;
    const cv::Point2d at = m.camera.camera.project(centre);
    const double place_px = kSpinCheckPlace * m.camera.camera.fx() * part.db.diameter_mm / centre[2];
    for (int j = i + 1; j < begin + pool; ++j) {
      const Verified& r = m.verified[j];
      if (r.hit.part != v.hit.part || r.fit_score <= 0 || r.fit_score < kFlipMinScoreRatio * current.score) continue;
      if (cv::norm(m.camera.camera.project(r.fitted.R * part.db.center_mm + r.fitted.t_mm) - at) > place_px) continue;
      // The normal either way: a plate face down is the turned-over check's.
      if (degrees(std::acos(std::min(1.0, std::abs(n.dot(normal(r.fitted)))))) > kSpinCheckMaxAxisDeg) continue;
      // Over the symmetry's turns about z, computed (discrete_rotations() would allocate).
      double spin = 180;
      for (int k = 0; k < sym.order; ++k)
        spin = std::min(spin, degrees(rotation_angle(current.pose.R.t() * r.fitted.R *
                                                     rotation_about_z(2 * CV_PI * k / sym.order))));
      if (spin < kSpinCheckMinSpinDeg) continue;
      const TemplateFitResult rival = r.as_fit();
      if (!turn_is_better(m.fitter.compare(part.db, current, rival, m.camera.camera, ws))) continue;
      current = rival;
      // As a turn: the hypothesis takes the rival's pose and keeps its own rank.
      v.take(rival, std::max(v.fit_rank, r.fit_rank));
    }
  }
}

void BinPickingPipeline::Impl::add_search(const Cycle& cycle, const LineSet& query,
                                          const IntegralDistanceTransform& idt, size_t wanted,
                                          const SearchSettings& settings, int round, PipelineResult& out) {
  Cycle later = cycle;
  later.minimum_past_deadline = false;
  later.search_deadline = cycle.deadline;
  search(later, query, &idt, wanted, settings, out);
  if (!hits.empty()) prepare_fitter();
  const size_t first = verified.size();
  verify(wanted);
  fit(later, first, &idt);
  if (config.trace) trace(first, round, out);
  rank(later, first);
  sort_verified(0);
}

// The query of a later search round: the cycle's query lines and directional edge map without
// the image edges that the best `best` distinct candidates so far explain (those within
// kRoundErasePx of their fitted view's points; distinct as the candidates' NMS sees them). A line
// is dropped when more than half of it lies there.
void BinPickingPipeline::Impl::query_without_best(int best) {
  Impl& m = *this;
  // (Plain loops: cv::Mat::setTo allocates a scalar buffer on every call.)
  for (int y = 0; y < erased.rows; ++y) std::fill_n(erased.ptr<uchar>(y), erased.cols, uchar{0});
  std::array<cv::Rect2d, PipelineConfig::kMaxSearchRounds> taken;
  int n = 0;
  for (const Verified& v : m.verified) {
    if (n >= best) break;
    bool overlaps = false;
    for (int k = 0; k < n; ++k) overlaps = overlaps || iou(taken[static_cast<size_t>(k)], v.hit.box) > kCandidateOverlap;
    if (overlaps) continue;
    taken[static_cast<size_t>(n++)] = v.hit.box;
    const TemplateView& view = m.parts[v.hit.part].db.views[static_cast<size_t>(v.view)];
    for_each_projected_point(view, v.fitted, m.camera.camera, [&](const cv::Point2d& q) {
      const cv::Rect around(cvRound(q.x) - kRoundErasePx, cvRound(q.y) - kRoundErasePx, 2 * kRoundErasePx + 1,
                            2 * kRoundErasePx + 1);
      const cv::Rect inside = around & cv::Rect(cv::Point(0, 0), erased.size());
      for (int y = inside.y; y < inside.y + inside.height; ++y)
        std::fill_n(erased.ptr<uchar>(y) + inside.x, inside.width, uchar{255});
    });
  }
  m.lines.channelMap.copyTo(round_query.channelMap);
  for (int y = 0; y < erased.rows; ++y) {
    const uchar* gone = erased.ptr<uchar>(y);
    uchar* channel = round_query.channelMap.ptr<uchar>(y);
    for (int x = 0; x < erased.cols; ++x)
      if (gone[x]) channel[x] = kNoChannel;
  }
  const LineSet& all = m.lines.set;
  round_query.set.q = all.q;
  round_query.set.oriented = all.oriented;
  round_query.set.size = all.size;
  round_query.set.origin = all.origin;
  round_query.set.lines.clear();
  for (const LineSegment& line : all.lines) {
    const int steps = std::max(1, static_cast<int>(std::ceil(line.length())));
    int gone = 0;
    for (int k = 0; k <= steps; ++k) {
      const cv::Point2f at = line.a + (line.b - line.a) * (static_cast<float>(k) / static_cast<float>(steps));
      const int x = cvRound(at.x), y = cvRound(at.y);
      gone += x >= 0 && y >= 0 && x < erased.cols && y < erased.rows && erased(y, x) != 0;
    }
    if (2 * gone <= steps + 1) round_query.set.lines.push_back(line);
  }
}

std::pair<const LineSet*, const cv::Mat1b*> BinPickingPipeline::Impl::search_query(const LineFitResult& q) {
  const int down = config.search_downsample;
  if (down <= 1) return {&q.set, &q.channelMap};
  reduceQuery(q.set, q.channelMap, down, search_lines, search_channels);
  return {&search_lines, &search_channels};
}

void BinPickingPipeline::process(const MfcFrames& frames, int obj_id, Clock::time_point deadline,
                                 PipelineResult& out) {
  Impl& m = *impl_;
  const auto t0 = Clock::now();
  const OmpThreadsInScope team(m.config.threads);
  out.candidates.clear();
  out.degraded = false;
  out.times = {};

  bool known = obj_id == 0;
  for (const auto& p : m.parts) known = known || p.db.obj_id == obj_id;
  if (!known) throw std::invalid_argument("pipeline: no templates loaded for obj_id " + std::to_string(obj_id));

  m.extractor.extract(frames, m.edges);
  m.fitter_prepared = false;
  auto t = Clock::now();
  out.times.edges_ms = ms_between(t0, t);

  m.line_fitter.fit(m.edges.edges, &m.edges.direction, m.lines, m.dt3_params.oriented ? &m.edges.shadow : nullptr);
  const LineFitResult& fit = m.lines;
  out.edge_pixels = fit.inputEdgePixels;
  out.query_lines = static_cast<int>(fit.set.lines.size());
  auto t1 = Clock::now();
  out.times.lines_ms = ms_between(t, t1);

  const bool fdcm = m.config.cost == PipelineConfig::Cost::fdcm;
  const auto [query, search_map] = m.search_query(fit);
  if (fdcm) {
    m.dt3.compute(*search_map, m.search_dt3);
    m.idt.compute(m.dt3);
  } else {
    m.chamfer.compute(*search_map, m.search_dt3);
  }
  t = Clock::now();
  out.times.distance_ms = ms_between(t1, t);

  // Search: the 1-D line search (paper Sec. 4.4) over every view of every selected part, views
  // shared out among the threads. Past the search's deadline the remaining views are skipped: it
  // leaves the hypothesis fit the time it took last cycle, with a margin.
  // At most half the time left goes to the fit: the search always gets the other half.
  Impl::Cycle cycle;
  cycle.obj_id = obj_id;
  cycle.fdcm = fdcm;
  cycle.deadline = deadline;
  m.budget->start(deadline);
  cycle.search_deadline = m.budget->search_deadline();
  for (const auto& part : m.parts) cycle.selected_parts += obj_id == 0 || part.db.obj_id == obj_id;
  out.hypotheses = 0;
  out.views_searched = 0;
  m.search(cycle, *query, fdcm ? &m.idt : nullptr, static_cast<size_t>(m.config.fit_candidates), m.shipped_search(),
           out);
  out.degraded = cycle.late;
  t1 = Clock::now();
  out.times.search_ms = ms_between(t, t1);

  // Verification, then each hypothesis fitted in 6-DoF and ranked (Impl::verify, fit, rank).
  m.verified.clear();
  out.trace.clear();
  const auto fit_start = Clock::now();
  if (fdcm && !m.hits.empty()) m.prepare_fitter();
  m.verify(static_cast<size_t>(m.config.fit_candidates));
  m.fit(cycle, 0, fdcm ? &m.idt : nullptr);
  out.degraded = out.degraded || cycle.fit_late;
  // The time the fit of all hypotheses takes, from the fits that ran (the search leaves it that).
  m.budget->record_fit(ms_between(fit_start, Clock::now()), static_cast<int>(m.verified.size()),
                      m.config.fit_candidates);
  if (m.config.trace) m.trace(0, 1, out);
  m.rank(cycle, 0);

  // Escalation (PipelineConfig::escalate_below): nothing the cell would pick, so the same query
  // is searched again wide, and its new hypotheses are fitted and ranked with the first ones.
  // Like a later round it only adds candidates: skipped near the deadline, it degrades nothing.
  out.escalated = false;
  if (fdcm && m.config.fit_hypotheses && m.config.escalate_below > 0 && !out.degraded &&
      (m.verified.empty() || m.verified.front().fit_rank < m.config.escalate_below) &&
      m.budget->leaves_time_for(CycleBudget::Optional::escalation)) {
    const auto escalation_start = Clock::now();
    m.add_search(cycle, *query, m.idt, static_cast<size_t>(m.config.escalate_hypotheses), m.escalation_search(), 0,
                 out);
    m.budget->record(CycleBudget::Optional::escalation, ms_between(escalation_start, Clock::now()));
    out.escalated = true;
  }

  // Later search rounds (PipelineConfig::search_rounds): the image edges the best candidates so
  // far explain are taken out of the query and the search runs again for the parts they hid.
  // A round starts only when the first was complete and the deadline leaves it the time the last
  // one took; its result is extra candidates, so skipping it does not degrade the cycle.
  out.rounds = 1;
  for (int round = 2; fdcm && round <= m.config.search_rounds && !out.degraded && !m.verified.empty(); ++round) {
    const auto round_start = Clock::now();
    if (!m.budget->leaves_time_for(CycleBudget::Optional::round)) break;
    m.query_without_best(round - 1);
    const auto [round_lines, round_map] = m.search_query(m.round_query);
    m.dt3.compute(*round_map, m.search_dt3);
    m.round_idt.compute(m.dt3);
    m.add_search(cycle, *round_lines, m.round_idt, static_cast<size_t>(m.config.round_hypotheses), m.shipped_search(),
                 round, out);
    m.budget->record(CycleBudget::Optional::round, ms_between(round_start, Clock::now()));
    out.rounds = round;
  }

  // Non-maximum suppression across views and part types: one part per place in the bin.
  const int down = m.config.search_downsample;  // the search hits' pixels
  bool final_prepared = false;
  for (const Impl::Verified& v : m.verified) {
    const Hit& h = v.hit;
    if (static_cast<int>(out.candidates.size()) >= m.config.max_candidates) break;
    bool overlaps = false;
    for (const auto& k : out.candidates) overlaps = overlaps || iou(k.box, h.box) > kCandidateOverlap;
    if (overlaps) continue;
    const PartModel& part = m.parts[h.part];
    PoseCandidate c;
    c.obj_id = part.db.obj_id;
    c.part = part.db.part_name;
    c.view = v.view;
    c.R_m2c = v.fitted.R;
    c.t_m2c_mm = v.fitted.t_mm;
    c.cost_px = h.c.cost() * down;
    c.coverage = v.coverage;
    c.rank_px = v.combined;
    c.fit_rank = v.fit_rank;
    // 1 at a perfect match, 0.5 at 2 px of combined cost, falling slowly so that a correct but
    // unrefined match of a large part (3-4 px) still ranks above nothing.
    c.score = v.fit_score >= 0 ? std::clamp(v.fit_rank, 0.0, 1.0) : 1.0 / (1.0 + v.combined / 2.0);
    c.box = h.box;
    // (Past the deadline the candidate keeps the ranking fit's pose.)
    if (v.fit_score >= 0 && m.config.edge_offset_correction && Clock::now() < deadline) {
      if (!final_prepared) m.final_fitter.share_prepared(m.fitter), final_prepared = true;
      const TemplateFitResult f = m.final_fitter.fit(part.db, v.view, v.fitted, m.camera.camera, m.fit_workspaces[0]);
      // The bin floor binds this fit as every other: one that slid through it keeps the ranked pose.
      if (!m.config.floor.below(part.db.mesh, f.pose)) {
        c.R_m2c = f.pose.R;
        c.t_m2c_mm = f.pose.t_mm;
        c.view = f.view;
      }
    }
    out.candidates.push_back(std::move(c));
  }
  t = Clock::now();
  out.times.pose_ms = ms_between(t1, t);

  // Multi-view refinement (paper Sec. 4.5; one view here: the cell's single MFC capture) of the
  // best candidates, until the deadline. A candidate whose refinement fails keeps its coarse pose.
  const int refine = m.config.refine_iterations > 0
                         ? std::min<int>(m.config.refine_candidates, static_cast<int>(out.candidates.size()))
                         : 0;
  if (refine > 0 && Clock::now() < deadline) {
    if (!m.renderer) {
      m.renderer = std::make_unique<MfcRenderer>(m.camera);
      for (const auto& part : m.parts) m.mesh_ids.push_back(m.renderer->add_mesh(part.db.mesh));
      RefinerParams rp;
      rp.max_iterations = m.config.refine_iterations;
      m.refiner = std::make_unique<PoseRefiner>(*m.renderer, rp);
    }
    const RefinementView view{&m.edges, m.camera.camera, RigidTransform{}};
    m.refiner->prepare(std::span<const RefinementView>(&view, 1));
    for (int i = 0; i < refine; ++i) {
      if (Clock::now() >= deadline) {
        out.degraded = true;
        break;
      }
      PoseCandidate& c = out.candidates[i];
      int part = 0;
      while (m.parts[part].db.obj_id != c.obj_id) ++part;
      const RefinementResult r = m.refiner->refine(pose_model(m.mesh_ids[part], m.parts[part].db.mesh),
                                                  RigidTransform{c.R_m2c, c.t_m2c_mm}, deadline);
      out.degraded = out.degraded || r.deadline_hit;
      if (r.failed) continue;
      // One view constrains depth and tilt weakly; a refinement that ends worse than it started
      // (by the same Eq. 21 measure) walked into a false minimum: keep the coarse pose then.
      const RefinementResult start =
          m.refiner->evaluate(pose_model(m.mesh_ids[part], m.parts[part].db.mesh), RigidTransform{c.R_m2c, c.t_m2c_mm});
      // Depth is where one view is weakest: a flat part can trade distance for tilt. The coarse
      // distance was measured from the image scale (fit_distance, 1 % steps, then the hypothesis fit), so a refinement that
      // moves the part centre along the line of sight by more than 4 % of its distance is not
      // trusted either.
      const cv::Vec3d c0 = c.R_m2c * m.parts[part].db.center_mm + c.t_m2c_mm;
      const cv::Vec3d c1 = r.pose.R * m.parts[part].db.center_mm + r.pose.t;
      const bool depth_jump = std::abs(cv::norm(c1) - cv::norm(c0)) > 0.04 * cv::norm(c0);
      if (r.score < start.score || depth_jump) {
        c.cost_px = start.mean_cost_px;
        continue;
      }
      c.R_m2c = r.pose.R;
      c.t_m2c_mm = r.pose.t;
      c.cost_px = r.mean_cost_px;
      c.refined = true;
    }
    // The order stays the fitted ranking's (TemplatePoseFit with the unexplained-edge check): the
    // refiner polishes a pose, its score (model edges found, no converse check) does not tell a
    // part from its own back or from clutter as well.
  }
  // Grasp features at the final poses: edges and the part's own points only, ~0.1 ms each.
  for (PoseCandidate& c : out.candidates) {
    bool any = false;
    double best = 0;
    for (const auto& [feature_obj_id, feature] : m.config.grasp_features)
      if (feature_obj_id == c.obj_id) {
        any = true;
        best = std::max(best, grasp_visibility(c.obj_id, c.R_m2c, c.t_m2c_mm, feature).visible);
      }
    c.grasp_visibility = any ? best : 1.0;
  }
  const auto t2 = Clock::now();
  out.times.refine_ms = ms_between(t, t2);
  t = t2;
  out.times.total_ms = ms_between(t0, t);
}

PoseScore BinPickingPipeline::score_pose(int obj_id, const cv::Matx33d& R_m2c, const cv::Vec3d& t_m2c_mm) {
  Impl& m = *impl_;
  if (m.config.cost != PipelineConfig::Cost::fdcm) throw std::invalid_argument("pipeline: score_pose needs the FDCM cost");
  const PartModel& part = m.part_of(obj_id);
  // The nearest view over the part's symmetric copies of the pose (the views cover one wedge),
  // as the hypothesis fit chooses it.
  PoseScore out;
  RigidPose pose{R_m2c, t_m2c_mm};
  out.view = TemplatePoseFit::nearest_view(part.db, m.camera.camera, pose);
  TemplatePlacement placement = placement_of(part.db, out.view, pose, m.camera.camera);
  const double best = rotation_angle(coarse_pose(part.db, placement, m.camera.camera).R.t() * pose.R);
  out.view_angle_deg = best * 180.0 / CV_PI;
  const TemplateView& view = part.db.views[static_cast<size_t>(out.view)];
  out.cost_px = fit_distance(view.lines, m.idt, m.config.search_downsample, placement, m.distance_workspaces[0]);
  if (!std::isfinite(out.cost_px)) out.cost_px = m.dt3_params.maxCost;
  const Warp w{placement.angle_rad, placement.scale, 1.0};
  out.coverage = explained_fraction(view, w, static_cast<int>(placement.origin_px.x),
                                    static_cast<int>(placement.origin_px.y), m.edges.edges, m.fit_workspaces[0]);
  out.rank_px = out.cost_px + kUnexplainedPenaltyPx * (1.0 - out.coverage);
  m.prepare_fitter();
  const RigidPose start = coarse_pose(part.db, placement, m.camera.camera);
  // Scored as a best hypothesis of the cycle is (PipelineConfig::rescore_hypotheses).
  const TemplateFitResult f =
      m.scored_like(0, part.db, m.fitter.fit(part.db, out.view, start, m.camera.camera, m.fit_workspaces[0]));
  out.fit_score = fitted_rank(f, part.db, m.config);
  const TemplateFitResult exact = m.fitter.evaluate(part.db, out.view, pose, m.camera.camera, m.fit_workspaces[0],
                                                    TemplatePoseFit::kAllPoints);
  out.exact_score = fitted_rank(exact, part.db, m.config);
  return out;
}

void BinPickingPipeline::draw_pose(cv::Mat3b& image, int obj_id, const cv::Matx33d& R_m2c, const cv::Vec3d& t_m2c_mm,
                                   const cv::Scalar& colour) const {
  const Impl& m = *impl_;
  const PartModel& part = m.part_of(obj_id);
  RigidPose pose{R_m2c, t_m2c_mm};
  const int view = TemplatePoseFit::nearest_view(part.db, m.camera.camera, pose);
  const cv::Vec3b c(cv::saturate_cast<uchar>(colour[0]), cv::saturate_cast<uchar>(colour[1]),
                    cv::saturate_cast<uchar>(colour[2]));
  for_each_projected_point(part.db.views[static_cast<size_t>(view)], pose, m.camera.camera, [&](const cv::Point2d& q) {
    const cv::Point px(static_cast<int>(std::lround(q.x)), static_cast<int>(std::lround(q.y)));
    if (px.x >= 0 && px.y >= 0 && px.x < image.cols && px.y < image.rows) image(px) = c;
  });
}

GraspVisibility BinPickingPipeline::grasp_visibility(int obj_id, const cv::Matx33d& R_m2c, const cv::Vec3d& t_m2c_mm,
                                                     const GraspFeature& feature) {
  Impl& m = *impl_;
  const PartModel& part = m.part_of(obj_id);
  return grasp_feature_visibility(m.edges, part.db, m.camera.camera, RigidPose{R_m2c, t_m2c_mm}, feature,
                                  m.config.fit_inlier_cost_px, m.own_edges);
}

cv::Mat3b draw_candidates(const cv::Mat1b& image, const PipelineResult& result, const CameraConfig& camera) {
  cv::Mat3b out;
  cv::cvtColor(image, out, cv::COLOR_GRAY2BGR);
  static const cv::Scalar colours[] = {{0, 255, 0}, {0, 200, 255}, {255, 120, 0}, {255, 0, 255}, {0, 0, 255}};
  for (size_t i = 0; i < result.candidates.size(); ++i) {
    const auto& c = result.candidates[i];
    const cv::Scalar col = colours[i % 5];
    cv::rectangle(out, c.box, col, 1);
    const cv::Point2d centre = camera.camera.project(c.t_m2c_mm);
    cv::circle(out, centre, 3, col, -1);
    char label[96];
    std::snprintf(label, sizeof label, "#%zu %s %.2f", i + 1, c.part.c_str(), c.score);
    cv::putText(out, label, cv::Point(static_cast<int>(c.box.x), std::max(12, static_cast<int>(c.box.y) - 4)),
                cv::FONT_HERSHEY_SIMPLEX, 0.45, col, 1, cv::LINE_AA);
  }
  return out;
}

}  // namespace mfcd::vision
