#include "vision/pipeline/bin_picking_pipeline.hpp"
#include "vision/pipeline/stage.hpp"

#include <opencv2/imgproc.hpp>

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace mfcd::vision {

namespace {

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
  const int threads = m.config.threads > 0 ? m.config.threads : omp_get_max_threads();
  find_turns(m.parts, threads);
  try {
    m.config.floor.validate();
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(std::string("pipeline: ") + e.what());
  }
  for (const auto& [obj_id, feature] : m.config.grasp_features) {
    bool loaded = false;
    for (const auto& p : m.parts) loaded = loaded || p.db.obj_id == obj_id;
    if (!loaded)
      throw std::runtime_error("pipeline: a grasp feature names obj_id " + std::to_string(obj_id) +
                               ", which no template file defines");
    const std::string why = feature.validate();
    if (!why.empty())
      throw std::runtime_error("pipeline: grasp feature of obj_id " + std::to_string(obj_id) + ": " + why);
  }
  m.dt3_params.polarityPenalty = m.config.search_polarity_penalty_px;
  m.search_dt3 = m.dt3_params;
  m.search_dt3.lambda /= m.config.search_downsample;
  m.search_dt3.maxCost /= m.config.search_downsample;
  m.search_dt3.polarityPenalty /= m.config.search_downsample;
  m.thread_hits.resize(static_cast<size_t>(threads));
  m.thread_hypotheses.resize(static_cast<size_t>(threads));
  m.thread_views.resize(static_cast<size_t>(threads));
  for (auto& h : m.thread_hits) h.reserve(4096);
  m.thread_best.resize(static_cast<size_t>(threads));
  for (auto& h : m.thread_best)
    h.reserve(
        std::max<size_t>({std::max(m.most_fitted(), static_cast<size_t>(m.config.round_hypotheses)) *
                              static_cast<size_t>(m.config.keep_per_view),
                          static_cast<size_t>(m.config.escalate_hypotheses * m.config.escalate_placements_per_view),
                          m.config.coarse_seeds * m.parts.size()}) +
        1);
  m.hits.reserve(4096);
  m.verified.reserve(m.most_fitted() +
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
  m.budget.emplace(threads);
  m.erased = cv::Mat1b::zeros(camera.camera.image_size);
  // The pick cycle, stage by stage (stage.hpp).
  for (auto make :
       {make_edges_stage, make_lines_stage, make_distance_stage, make_search_stage, make_fit_stage, make_ranking_stage,
        make_escalation_stage, make_rounds_stage, make_candidates_stage, make_refinement_stage, make_grasp_stage})
    m.stages.push_back(make());
}

BinPickingPipeline::~BinPickingPipeline() = default;

std::vector<std::pair<int, std::string>> BinPickingPipeline::parts() const {
  std::vector<std::pair<int, std::string>> out;
  for (const auto& p : impl_->parts) out.emplace_back(p.db.obj_id, p.db.part_name);
  return out;
}
const CameraConfig& BinPickingPipeline::camera() const { return impl_->camera; }
const DepthEdges& BinPickingPipeline::last_edges() const { return impl_->edges; }

void BinPickingPipeline::process(const MfcFrames& frames, int obj_id, Clock::time_point deadline, PipelineResult& out) {
  Impl& m = *impl_;
  const auto t0 = Clock::now();
  const OmpThreadsInScope team(m.config.threads);
  out.candidates.clear();
  out.degraded = false;
  out.times = {};

  bool known = obj_id == 0;
  for (const auto& p : m.parts) known = known || p.db.obj_id == obj_id;
  if (!known) throw std::invalid_argument("pipeline: no templates loaded for obj_id " + std::to_string(obj_id));

  CycleContext c;
  c.frames = &frames;
  c.out = &out;
  c.cycle.obj_id = obj_id;
  c.cycle.fdcm = m.config.cost == PipelineConfig::Cost::fdcm;
  c.cycle.deadline = deadline;
  for (const auto& part : m.parts) c.cycle.selected_parts += obj_id == 0 || part.db.obj_id == obj_id;
  m.budget->start(deadline);
  auto t = t0;
  for (const auto& stage : m.stages) {
    stage->run(m, c);
    const auto now = Clock::now();
    out.times.*stage->time() += ms_between(t, now);
    t = now;
  }
  out.times.total_ms = ms_between(t0, t);
}

void BinPickingPipeline::set_floor(const BinFloor& floor) {
  floor.validate();
  impl_->config.floor = floor;
}

PoseScore BinPickingPipeline::score_pose(int obj_id, const cv::Matx33d& R_m2c, const cv::Vec3d& t_m2c_mm) {
  Impl& m = *impl_;
  if (m.config.cost != PipelineConfig::Cost::fdcm)
    throw std::invalid_argument("pipeline: score_pose needs the FDCM cost");
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
  const TemplateFitResult exact =
      m.fitter.evaluate(part.db, out.view, pose, m.camera.camera, m.fit_workspaces[0], TemplatePoseFit::kAllPoints);
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
  return impl_->grasp_visibility(obj_id, RigidPose{R_m2c, t_m2c_mm}, feature);
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
