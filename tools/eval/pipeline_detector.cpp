// FDCM, OCM and CM: the bin-picking pipeline with each matching cost.
#include "tools/eval/detectors.hpp"

#include "tools/common/cli_numbers.hpp"

#include <opencv2/imgproc.hpp>

#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

namespace mfcd::eval {

namespace {

class PipelineDetector final : public Detector {
 public:
  PipelineDetector(std::string name, vision::PipelineConfig::Cost cost, const vision::CameraConfig& camera,
                   const std::vector<std::filesystem::path>& templates, int threads, int max_candidates,
                   const std::vector<double>& distances_mm, int refine_candidates, bool fit_hypotheses,
                   const std::vector<std::string>& settings,
                   const std::vector<std::pair<int, vision::GraspFeature>>& grasp_features)
      : name_(std::move(name)), cost_(cost) {
    const auto t0 = std::chrono::steady_clock::now();
    vision::PipelineConfig pc;
    pc.cost = cost;
    pc.template_files = templates;
    pc.threads = threads;
    pc.max_candidates = max_candidates;
    pc.distances_mm = distances_mm;
    pc.fit_hypotheses = fit_hypotheses;
    if (refine_candidates >= 0) pc.refine_candidates = refine_candidates;
    pc.grasp_features = grasp_features;
    for (const auto& s : settings) apply_pipeline_setting(pc, s);
    pipeline_ = std::make_unique<vision::BinPickingPipeline>(camera, pc);
    setup_s_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  std::string name() const override { return name_; }
  void detect(const vision::MfcFrames& frames, int obj_id, Detection& out) override {
    // No deadline: the evaluation measures the full search of every method.
    pipeline_->process(frames, obj_id, std::chrono::steady_clock::now() + std::chrono::hours(1), result_);
    out.estimates.clear();
    for (const auto& c : result_.candidates)
      out.estimates.push_back({c.obj_id, c.R_m2c, c.t_m2c_mm, c.score, c.rank_px, c.fit_rank, c.grasp_visibility, {}});
    out.times = result_.times;
    out.views_searched = result_.views_searched;
    out.evaluated = result_.hypotheses;
    out.escalated = result_.escalated;
    out.coarse_hypotheses.clear();
    out.fitted_hypotheses.clear();
    for (const auto& h : result_.trace) {
      out.coarse_hypotheses.push_back({h.obj_id, h.R_coarse, h.t_coarse_mm, 0, h.search_cost_px, h.fit_rank, 1, {}});
      out.fitted_hypotheses.push_back({h.obj_id, h.R_fitted, h.t_fitted_mm, 0, h.search_cost_px, h.fit_rank, 1,
                                       {{"search_cost_px", h.search_cost_px},
                                        {"search_coverage", h.coverage},
                                        {"fit_score", h.fit_score},
                                        {"fit_coverage", h.fit_coverage},
                                        {"inlier_fraction", h.inlier_fraction},
                                        {"mean_cost_px", h.mean_cost_px},
                                        {"view_points", h.view_points},
                                        {"round", static_cast<double>(h.round)}}});
    }
  }
  std::optional<vision::PoseScore> score_pose(int obj_id, const cv::Matx33d& R, const cv::Vec3d& t_mm) override {
    if (cost_ != vision::PipelineConfig::Cost::fdcm) return std::nullopt;
    return pipeline_->score_pose(obj_id, R, t_mm);
  }
  std::optional<vision::GraspVisibility> grasp_visibility(int obj_id, const cv::Matx33d& R, const cv::Vec3d& t_mm,
                                                          const vision::GraspFeature& feature) override {
    if (cost_ != vision::PipelineConfig::Cost::fdcm) return std::nullopt;
    return pipeline_->grasp_visibility(obj_id, R, t_mm, feature);
  }
  std::optional<cv::Mat3b> overlay(int obj_id, const std::vector<DrawnPose>& poses) const override {
    const cv::Mat1b& edges = pipeline_->last_edges().edges;
    if (edges.empty()) return std::nullopt;
    cv::Mat1b dim = edges * (110.0 / 255.0);
    cv::Mat3b out;
    cv::cvtColor(dim, out, cv::COLOR_GRAY2BGR);
    // Each pose's points in its colour where an image edge lies under them (within 1 px) and dimmed
    // where none does, so that the overlay shows which of a pose's edges the image lacks.
    cv::Mat1b near_edge;
    cv::dilate(edges, near_edge, cv::Mat());
    for (const DrawnPose& p : poses) {
      cv::Mat3b drawn(out.size(), cv::Vec3b(0, 0, 0));
      pipeline_->draw_pose(drawn, obj_id, p.R, p.t_mm, p.colour);
      for (int y = 0; y < out.rows; ++y)
        for (int x = 0; x < out.cols; ++x) {
          const cv::Vec3b c = drawn(y, x);
          if (c == cv::Vec3b(0, 0, 0)) continue;
          out(y, x) = near_edge(y, x) ? c : cv::Vec3b(c[0] * 2 / 5, c[1] * 2 / 5, c[2] * 2 / 5);
        }
    }
    return out;
  }
  double setup_seconds() const override { return setup_s_; }

 private:
  std::string name_;
  vision::PipelineConfig::Cost cost_;
  std::unique_ptr<vision::BinPickingPipeline> pipeline_;
  vision::PipelineResult result_;
  double setup_s_ = 0;
};

}  // namespace

std::unique_ptr<Detector> make_pipeline_detector(const std::string& name, vision::PipelineConfig::Cost cost,
                                                 const vision::CameraConfig& camera,
                                                 const std::vector<std::filesystem::path>& templates, int threads,
                                                 int max_candidates, const std::vector<double>& distances_mm,
                                                 int refine_candidates, bool fit_hypotheses,
                                                 const std::vector<std::string>& settings,
                                                 const std::vector<std::pair<int, vision::GraspFeature>>& grasp_features) {
  return std::make_unique<PipelineDetector>(name, cost, camera, templates, threads, max_candidates, distances_mm,
                                            refine_candidates, fit_hypotheses, settings, grasp_features);
}

void apply_pipeline_setting(vision::PipelineConfig& c, const std::string& setting) {
  using Config = vision::PipelineConfig;
  // The settings an experiment may change, by their PipelineConfig names.
  static constexpr std::pair<const char*, double Config::*> kNumbers[] = {
      {"max_cost_px", &Config::max_cost_px},
      {"min_guide_overlap", &Config::min_guide_overlap},
      {"evidence_weight", &Config::evidence_weight}, {"escalate_below", &Config::escalate_below},
      {"fit_score_gate_px", &Config::fit_score_gate_px}, {"fit_inlier_cost_px", &Config::fit_inlier_cost_px},
      {"unexplained_weight", &Config::unexplained_weight}, {"escalate_max_cost_px", &Config::escalate_max_cost_px},
      {"search_polarity_penalty_px", &Config::search_polarity_penalty_px},
      {"depth_start_mm", &Config::depth_start_mm}};
  static constexpr std::pair<const char*, int Config::*> kIntegers[] = {
      {"template_guides", &Config::template_guides}, {"query_guides", &Config::query_guides},
      {"view_stride", &Config::view_stride},         {"coarse_seeds", &Config::coarse_seeds},
      {"keep_per_view", &Config::keep_per_view},     {"slide_step", &Config::slide_step},
      {"keep_separation_px", &Config::keep_separation_px},
      {"search_downsample", &Config::search_downsample}, {"fit_candidates", &Config::fit_candidates},
      {"max_candidates", &Config::max_candidates},   {"flip_checks", &Config::flip_checks},
      {"floor_starts", &Config::floor_starts},       {"rescore_hypotheses", &Config::rescore_hypotheses},
      {"search_rounds", &Config::search_rounds},
      {"round_hypotheses", &Config::round_hypotheses}, {"escalate_query_guides", &Config::escalate_query_guides},
      {"escalate_hypotheses", &Config::escalate_hypotheses}, {"depth_starts", &Config::depth_starts}};
  static constexpr std::pair<const char*, bool Config::*> kSwitches[] = {
      {"share_search_bound", &Config::share_search_bound}, {"trace", &Config::trace},
      {"edge_polarity", &Config::edge_polarity},         {"search_polarity", &Config::search_polarity},
      {"edge_offset_correction", &Config::edge_offset_correction}};
  const auto eq = setting.find('=');
  if (eq == std::string::npos) throw std::invalid_argument("'" + setting + "' is not key=value");
  const std::string key = setting.substr(0, eq), value = setting.substr(eq + 1);
  // The bin floor's fields (BinFloor), the floor's normal staying the optical axis.
  if (key == "floor_distance_mm" || key == "floor_tolerance_mm") {
    (key == "floor_distance_mm" ? c.floor.distance_mm : c.floor.tolerance_mm) = mfcd::tools::parse_double(key, value);
    c.floor.validate();
    return;
  }
  for (const auto& [name, field] : kNumbers)
    if (key == name) {
      c.*field = mfcd::tools::parse_double(key, value);
      return;
    }
  for (const auto& [name, field] : kIntegers)
    if (key == name) {
      c.*field = mfcd::tools::parse_int(key, value);
      return;
    }
  for (const auto& [name, field] : kSwitches)
    if (key == name) {
      c.*field = mfcd::tools::parse_int(key, value) != 0;
      return;
    }
  std::string known = "floor_distance_mm, floor_tolerance_mm";
  for (const auto& k : kNumbers) known += std::string(", ") + k.first;
  for (const auto& k : kIntegers) known += std::string(", ") + k.first;
  for (const auto& k : kSwitches) known += std::string(", ") + k.first + " (0/1)";
  throw std::invalid_argument("unknown key '" + key + "' (keys: " + known + ")");
}

}  // namespace mfcd::eval
