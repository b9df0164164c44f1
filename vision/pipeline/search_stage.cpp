// The FDCM search (paper Sec. 3.6, 4.3-4.4): coarse to fine line search, verification of its
// hits, later rounds and the escalation's wide search.
#include "vision/pipeline/stage.hpp"

#include "vision/common/parallel_for.hpp"

#include <omp.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

namespace mfcd::vision {

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
  lp.maxQueryToGuide = m.config.max_query_to_guide;
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
    parallel_for(static_cast<int>(first), static_cast<int>(m.jobs.size()), threads, 4, [&](int j) {
      // The first few views of every part are searched even when late (the jobs interleave the
      // parts), so that a late cycle still has hypotheses to give its best-so-far picks from.
      const bool always =
          cycle.minimum_past_deadline && static_cast<size_t>(j) < kAlwaysSearchedPerPart * cycle.selected_parts;
      if (!always && late.load(std::memory_order_relaxed)) return;
      if (!always && Clock::now() > cycle.search_deadline) {
        late = true;
        return;
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
        mine.push_back(
            {p, v, c.oriented, c, cv::Rect2d(box.x * down, box.y * down, box.width * down, box.height * down)});
        best.push_back(c);
        std::push_heap(best.begin(), best.end(), better);  // worst on top
        if (best.size() > useful) {
          std::pop_heap(best.begin(), best.end(), better);
          best.pop_back();
        }
        if (best.size() == useful)
          SharedCostBound::lower(m.shared_bound, best.front().sum, static_cast<uint32_t>(best.front().pixels));
      }
    });
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
    for (const auto& k : m.verified)
      duplicate = duplicate || (k.hit.part == h.part && iou(k.hit.box, h.box) > 0.8 && k.hit.view == h.view);
    if (duplicate) continue;
    Verified v;
    v.hit = h;
    m.verified.push_back(v);
  }
  // The coverages are independent of each other: shared out among the threads.
  const int threads = static_cast<int>(m.thread_hits.size());
  parallel_for(static_cast<int>(first), static_cast<int>(m.verified.size()), threads, 2, [&](int i) {
    Verified& v = m.verified[i];
    const Hit& h = v.hit;
    const PartModel& part = m.parts[h.part];
    v.coverage = explained_fraction(part.db.views[h.view], part.warps[h.warp], h.c.tx * down, h.c.ty * down,
                                    m.edges.edges, m.fit_workspaces[omp_get_thread_num()]);
    v.combined = h.c.cost() * down + kUnexplainedPenaltyPx * (1.0 - v.coverage);
  });
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
  // A round's hits only add candidates, but one ranked without its checks may be picked.
  out.degraded = out.degraded || later.checks_late;
  sort_verified(0);
}

// The query of a later search round: the cycle's query lines and directional edge map without
// the image edges that the best `best` distinct candidates so far explain (those within
// m.config.round_erase_px of their fitted view's points; distinct as the candidates' NMS sees them). A line
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
    for (int k = 0; k < n; ++k)
      overlaps = overlaps || iou(taken[static_cast<size_t>(k)], v.hit.box) > m.config.candidate_overlap;
    if (overlaps) continue;
    taken[static_cast<size_t>(n++)] = v.hit.box;
    const TemplateView& view = m.parts[v.hit.part].db.views[static_cast<size_t>(v.view)];
    for_each_projected_point(view, v.fitted, m.camera.camera, [&](const cv::Point2d& q) {
      const cv::Rect around(cvRound(q.x) - m.config.round_erase_px, cvRound(q.y) - m.config.round_erase_px,
                            2 * m.config.round_erase_px + 1, 2 * m.config.round_erase_px + 1);
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

namespace detail {

namespace {

// The first search: the 1-D line search (paper Sec. 4.4) over every view of every selected part,
// views shared out among the threads. Past its own deadline (CycleBudget::search_deadline) the
// remaining views are skipped.
class SearchStage final : public Stage {
 public:
  SearchStage() : Stage("search", &StageTimes::search_ms) {}
  void run(BinPickingPipeline::Impl& m, CycleContext& c) override {
    c.cycle.search_deadline = m.budget->search_deadline(static_cast<int>(m.fitted_in(c.cycle)));
    c.out->hypotheses = 0;
    c.out->views_searched = 0;
    m.search(c.cycle, *c.query, c.cycle.fdcm ? &m.idt : nullptr, m.fitted_in(c.cycle), m.shipped_search(), *c.out);
    c.out->degraded = c.cycle.late;
  }
};

// Escalation (PipelineConfig::escalate_below): nothing the cell would pick, so the same query is
// searched again wide, and its new hypotheses are fitted and ranked with the first ones. Like a
// later round it only adds candidates: skipped near the deadline, it degrades nothing.
class EscalationStage final : public Stage {
 public:
  EscalationStage() : Stage("escalation", &StageTimes::pose_ms) {}
  void run(BinPickingPipeline::Impl& m, CycleContext& c) override {
    c.out->escalated = false;
    if (c.cycle.fdcm && m.config.fit_hypotheses && m.config.escalate_below > 0 && !c.out->degraded &&
        (m.verified.empty() || m.verified.front().fit_rank < m.config.escalate_below) &&
        m.budget->leaves_time_for(CycleBudget::Optional::escalation)) {
      const auto start = Clock::now();
      m.add_search(c.cycle, *c.query, m.idt, static_cast<size_t>(m.config.escalate_hypotheses), m.escalation_search(),
                   0, *c.out);
      m.budget->record(CycleBudget::Optional::escalation, ms_between(start, Clock::now()));
      c.out->escalated = true;
    }
  }
};

// Later search rounds (PipelineConfig::search_rounds): the image edges the best candidates so far
// explain are taken out of the query and the search runs again for the parts they hid. A round
// starts only when the first was complete and the deadline leaves it the time the last one took;
// its result is extra candidates, so skipping it does not degrade the cycle.
class RoundsStage final : public Stage {
 public:
  RoundsStage() : Stage("rounds", &StageTimes::pose_ms) {}
  void run(BinPickingPipeline::Impl& m, CycleContext& c) override {
    PipelineResult& out = *c.out;
    out.rounds = 1;
    for (int round = 2; c.cycle.fdcm && round <= m.config.search_rounds && !out.degraded && !m.verified.empty();
         ++round) {
      const auto start = Clock::now();
      if (!m.budget->leaves_time_for(CycleBudget::Optional::round)) break;
      m.query_without_best(round - 1);
      const auto [round_lines, round_map] = m.search_query(m.round_query);
      m.dt3.compute(*round_map, m.search_dt3);
      m.round_idt.compute(m.dt3);
      m.add_search(c.cycle, *round_lines, m.round_idt, static_cast<size_t>(m.config.round_hypotheses),
                   m.shipped_search(), round, out);
      m.budget->record(CycleBudget::Optional::round, ms_between(start, Clock::now()));
      out.rounds = round;
    }
  }
};

}  // namespace

std::unique_ptr<Stage> make_search_stage() { return std::make_unique<SearchStage>(); }
std::unique_ptr<Stage> make_escalation_stage() { return std::make_unique<EscalationStage>(); }
std::unique_ptr<Stage> make_rounds_stage() { return std::make_unique<RoundsStage>(); }

}  // namespace detail

}  // namespace mfcd::vision
