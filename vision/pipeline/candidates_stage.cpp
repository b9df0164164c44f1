// Pick candidates from the ranked hypotheses: one per place in the bin (non-maximum suppression
// across views and part types), each polished with the templates' edge offset profiles.
#include "vision/pipeline/stage.hpp"

#include <algorithm>

namespace mfcd::vision {

PoseEvidence PoseCandidate::evidence() const {
  PoseEvidence e;
  e.fit_rank = fit_rank;
  e.coverage = coverage;
  e.inlier_fraction = inlier_fraction;
  e.fit_cost_px = fit_cost_px;
  e.has_alternative = has_alternative;
  e.alternative_margin = has_alternative ? fit_rank - alternative_rank : 0;
  e.alternative_support = has_alternative ? alternative_support : 0;
  return e;
}

void BinPickingPipeline::Impl::find_alternative(size_t index, PoseCandidate& c) {
  const Verified& v = verified[index];
  const PartModel& part = parts[v.hit.part];
  const TemplateFitResult mine = v.as_fit();
  TemplatePoseFit::Workspace& ws = fit_workspaces[0];
  // Best-ranked first: the first distinct one is the best alternative.
  for (size_t i = 0; i < verified.size(); ++i) {
    const Verified& u = verified[i];
    if (i == index || u.fit_score < 0 || u.below_floor || u.hit.part != v.hit.part) continue;
    if (iou(u.hit.box, v.hit.box) <= config.candidate_overlap) continue;
    // Another answer: the part moved or turned beyond what the confidence calls right, over its
    // symmetries. How much its edges differ is the evidence, not the test: a twin whose edges
    // are this pose's own is what makes a pose ambiguous.
    const cv::Vec3d centre = mine.pose.R * part.db.center_mm + mine.pose.t_mm;
    const cv::Vec3d other = u.fitted.R * part.db.center_mm + u.fitted.t_mm;
    if (cv::norm(centre - other) < kDistinctPositionMm &&
        part.symmetries.angle_deg(mine.pose.R, u.fitted.R) < kDistinctRotationDeg)
      continue;
    const TemplatePoseFit::Difference d = fitter.compare(part.db, mine, u.as_fit(), camera.camera, ws);
    const double points = static_cast<double>(ws.seen_a.size() + ws.seen_b.size());
    const double differs = points > 0 ? (d.only_a + d.only_b) / points : 0;
    if (differs < config.alternative_min_differ) continue;
    c.has_alternative = true;
    c.alternative_rank = u.fit_rank;
    c.alternative_differs = differs;
    c.alternative_support = d.found_a - d.found_b;
    return;
  }
}

void BinPickingPipeline::Impl::make_candidates(Clock::time_point deadline, PipelineResult& out) {
  // Non-maximum suppression across views and part types: one part per place in the bin.
  const int down = config.search_downsample;  // the search hits' pixels
  bool final_prepared = false;
  for (const Impl::Verified& v : verified) {
    const Hit& h = v.hit;
    if (static_cast<int>(out.candidates.size()) >= config.max_candidates) break;
    bool overlaps = false;
    for (const auto& k : out.candidates) overlaps = overlaps || iou(k.box, h.box) > config.candidate_overlap;
    if (overlaps) continue;
    const PartModel& part = parts[h.part];
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
    c.inlier_fraction = v.fit.inlier_fraction;
    c.fit_cost_px = v.fit.mean_cost_px;
    c.box = h.box;
    // Past the deadline a fitted candidate goes without its alternative or its edge-offset fit:
    // the cycle is then degraded.
    const bool fitted = v.fit_score >= 0;
    if (fitted && Clock::now() < deadline)
      find_alternative(static_cast<size_t>(&v - verified.data()), c);
    else if (fitted)
      out.degraded = true;
    c.ambiguous = c.has_alternative && c.alternative_support < config.ambiguous_support;
    // Unfitted (the baselines): 1 at a perfect match, 0.5 at 2 px of combined cost.
    c.score = fitted ? config.confidence.probability(c.evidence()) : 1.0 / (1.0 + v.combined / 2.0);
    // (Past the deadline the candidate keeps the ranking fit's pose.)
    const bool correct = fitted && config.edge_offset_correction;
    const bool correct_in_time = correct && Clock::now() < deadline;
    if (correct && !correct_in_time) out.degraded = true;
    if (correct_in_time) {
      if (!final_prepared) final_fitter.share_prepared(fitter), final_prepared = true;
      const TemplateFitResult f = final_fitter.fit(part.db, v.view, v.fitted, camera.camera, fit_workspaces[0]);
      // The bin floor binds this fit as every other: one that slid through it keeps the ranked pose.
      if (!config.floor.below(part.db.mesh, f.pose)) {
        c.R_m2c = f.pose.R;
        c.t_m2c_mm = f.pose.t_mm;
        c.view = f.view;
      }
    }
    out.candidates.push_back(std::move(c));
  }
}

namespace detail {

namespace {

class CandidatesStage final : public Stage {
 public:
  CandidatesStage() : Stage("candidates", &StageTimes::pose_ms) {}
  void run(BinPickingPipeline::Impl& m, CycleContext& c) override { m.make_candidates(c.cycle.deadline, *c.out); }
};

}  // namespace

std::unique_ptr<Stage> make_candidates_stage() { return std::make_unique<CandidatesStage>(); }

}  // namespace detail

}  // namespace mfcd::vision
