// The hypothesis fit (Sec. 4.4): each hypothesis fitted in 6-DoF with its template's model points,
// and the measures its rank is made of.
#include "vision/pipeline/stage.hpp"

#include "vision/common/parallel_for.hpp"

#include <omp.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

namespace mfcd::vision {

namespace detail {

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
          const uint32_t stop = std::isfinite(best_cost) ? static_cast<uint32_t>(best_cost * kCostScale * t.pixels) + 1
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

}  // namespace detail

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
  parallel_for(begin, static_cast<int>(m.verified.size()), threads, 1, [&](int i) {
    Verified& v = m.verified[i];
    v.fit_score = -1;
    // Past the deadline only the first few (the best by search cost) are still fitted, so that a
    // late cycle still gives its best-so-far picks.
    const bool always = cycle.minimum_past_deadline && i - begin < kAlwaysFitted;
    v.skipped = !always && (fit_late.load(std::memory_order_relaxed) || Clock::now() > cycle.deadline);
    if (v.skipped) {
      fit_late = true;
      return;
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
        return;
      }
      // No part can lie there. About half of the fitted hypotheses of a full bin do (dev set 7:
      // 555 of 1000); fitting them again from the floor cost ~5 ms a cycle for no measured gain.
      v.below_floor = floor.below(part.db.mesh, f.pose);
      if (v.below_floor) return;
      v.take(f, fitted_rank(f, part.db, m.config));
    } else {
      // The search's distance is one of a few guesses: a pose below the floor goes onto it.
      v.fitted = floor.onto_if_below(part.db.mesh, v.coarse, part.db.center_mm);
    }
  });
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

namespace detail {

namespace {

// Verification, then each hypothesis fitted in 6-DoF (Impl::verify, fit). The time the fit of
// all hypotheses takes, from the fits that ran, is what the next cycle's search leaves it.
class FitStage final : public Stage {
 public:
  FitStage() : Stage("fit", &StageTimes::pose_ms) {}
  void run(BinPickingPipeline::Impl& m, CycleContext& c) override {
    m.verified.clear();
    c.out->trace.clear();
    const auto start = Clock::now();
    if (c.cycle.fdcm && !m.hits.empty()) m.prepare_fitter();
    m.verify(m.fitted_in(c.cycle));
    m.fit(c.cycle, 0, c.cycle.fdcm ? &m.idt : nullptr);
    c.out->degraded = c.out->degraded || c.cycle.fit_late;
    m.budget->record_fit(ms_between(start, Clock::now()), static_cast<int>(m.verified.size()));
    if (m.config.trace) m.trace(0, 1, *c.out);
  }
};

}  // namespace

std::unique_ptr<Stage> make_fit_stage() { return std::make_unique<FitStage>(); }

}  // namespace detail

}  // namespace mfcd::vision
