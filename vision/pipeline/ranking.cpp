// Ranking of the fitted hypotheses and the checks of the leading ones (rescoring, depth, floor
// and turn checks, the spin check).
#include "vision/pipeline/stage.hpp"

#include "vision/common/parallel_for.hpp"

#include <omp.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

namespace mfcd::vision {

// Best first from `first` on: by the fitted rank, or without the fit (the baselines, search
// only) by the search's combined cost.
void BinPickingPipeline::Impl::sort_verified(size_t first) {
  if (config.cost == PipelineConfig::Cost::fdcm && config.fit_hypotheses)
    stable_sort_in_place(
        verified, [](const Verified& a, const Verified& b) { return a.fit_rank > b.fit_rank; }, first);
  else
    stable_sort_in_place(
        verified, [](const Verified& a, const Verified& b) { return a.combined < b.combined; }, first);
}

// Ranks the hypotheses from `first` on, and checks the best few of them against the floor and
// turned over. A check the deadline skips sets cycle.checks_late.
void BinPickingPipeline::Impl::rank(Cycle& cycle, size_t first) {
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
  std::atomic<bool> late{false};
  auto check_leaders = [&](int n, auto&& check) {
    parallel_for(begin, begin + n, threads, 1, [&](int i) {
      Verified& v = m.verified[i];
      if (v.fit_score <= 0) return;
      if (Clock::now() > cycle.deadline) {
        late.store(true, std::memory_order_relaxed);
        return;
      }
      check(i, v, m.parts[v.hit.part]);
    });
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
  check_leaders(
      floor.known() ? std::min(m.config.floor_starts, count) : 0, [&](int i, Verified& v, const PartModel& part) {
        const double height = -floor.reach_below(part.db.mesh, v.fitted);
        if (height <= floor.tolerance_mm || height > m.config.floor_start_height_mm) return;
        const TemplateFitResult f = fit_from(i, part.db, floor.onto(part.db.mesh, v.fitted, part.db.center_mm));
        if (f.score < m.config.floor_start_min_score_ratio * v.fit_score || floor.below(part.db.mesh, f.pose) ||
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
      if (turn.screen) {
        TemplateFitResult twin = current;
        twin.pose = turned;
        twin.view = TemplatePoseFit::nearest_view(part.db, m.camera.camera, twin.pose);
        turned = twin.pose;
        if (!turn_is_better(m.fitter.compare(part.db, current, twin, m.camera.camera, ws,
                                             turn.flags_of_pose(current.view), turn.flags_of_turned(twin.view))))
          continue;
      }
      const TemplateFitResult f = fit_from(i, part.db, turned);
      if (moved_too_far_in_depth(part.db, v.coarse, f.pose) || f.score < kFlipMinScoreRatio * current.score ||
          floor.below(part.db.mesh, f.pose))
        continue;
      if (turn.by_rank) {
        if (v.fit_rank < kPlateTurnMinRank || fitted_rank(f, part.db, m.config) <= v.fit_rank) continue;
      } else {
        const TemplatePoseFit::Difference d = m.fitter.compare(
            part.db, current, f, m.camera.camera, ws, turn.flags_of_pose(current.view), turn.flags_of_turned(f.view));
        if (!turn_is_better(d)) continue;
      }
      current = f;
      // The turned pose replaces the fit, but never lowers the rank the hypothesis was sorted by.
      v.take(f, std::max(v.fit_rank, fitted_rank(f, part.db, m.config)));
    }
  });
  cycle.checks_late = cycle.checks_late || late.load();
  check_spins(cycle, first, rescored);
}

void BinPickingPipeline::Impl::check_spins(Cycle& cycle, size_t first, int pool) {
  Impl& m = *this;
  const int begin = static_cast<int>(first);
  const int leaders = std::min(kSpinCheckLeaders, pool);
  // Serial: a leader reads the lower hypotheses it is compared with, and few leaders qualify.
  auto& ws = m.fit_workspaces[0];
  for (int i = begin; i < begin + leaders; ++i) {
    Verified& v = m.verified[i];
    const PartModel& part = m.parts[v.hit.part];
    if (v.fit_score <= 0 || !part.plate_axis) continue;
    if (Clock::now() > cycle.deadline) {
      cycle.checks_late = true;
      continue;
    }
    const cv::Vec3d axis = *part.plate_axis;
    auto normal = [&](const RigidPose& p) { return p.R * axis; };
    // The half turn about the normal, the plate's symmetry.
    const cv::Matx33d half = axis_rotation(axis, CV_PI);
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
      // Over the plate's two turns about its normal.
      const cv::Matx33d relative = current.pose.R.t() * r.fitted.R;
      const double spin = degrees(std::min(rotation_angle(relative), rotation_angle(relative * half)));
      if (spin < kSpinCheckMinSpinDeg) continue;
      const TemplateFitResult rival = r.as_fit();
      if (!turn_is_better(m.fitter.compare(part.db, current, rival, m.camera.camera, ws))) continue;
      current = rival;
      // As a turn: the hypothesis takes the rival's pose and keeps its own rank.
      v.take(rival, std::max(v.fit_rank, r.fit_rank));
    }
  }
}

namespace detail {

namespace {

class RankingStage final : public Stage {
 public:
  RankingStage() : Stage("ranking", &StageTimes::pose_ms) {}
  void run(BinPickingPipeline::Impl& m, CycleContext& c) override {
    m.rank(c.cycle, 0);
    c.out->degraded = c.out->degraded || c.cycle.checks_late;
  }
};

}  // namespace

std::unique_ptr<Stage> make_ranking_stage() { return std::make_unique<RankingStage>(); }

}  // namespace detail

}  // namespace mfcd::vision
