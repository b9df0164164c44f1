// FDCM, OCM and CM: the bin-picking pipeline with each matching cost.
#include "tools/eval/detectors.hpp"

#include "tools/common/cli_numbers.hpp"
#include "vision/pipeline/pipeline_parameters.hpp"
#include "vision/templates/template_database.hpp"

#include <opencv2/imgproc.hpp>

#include <chrono>
#include <cmath>
#include <map>
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
      : name_(std::move(name)), cost_(cost), camera_(camera), templates_(templates) {
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
    for (const auto& s : settings) apply_eval_setting(pc, s);
    pipeline_ = std::make_unique<vision::BinPickingPipeline>(camera, pc);
    floor_ = pc.floor;
    setup_s_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  std::string name() const override { return name_; }
  void set_floor_mm(double distance_mm) override {
    vision::BinFloor floor = floor_;
    floor.distance_mm = distance_mm;
    pipeline_->set_floor(floor);
  }
  void detect(const vision::MfcFrames& frames, int obj_id, Detection& out) override {
    // No deadline: the evaluation measures the full search of every method.
    pipeline_->process(frames, obj_id, std::chrono::steady_clock::now() + std::chrono::hours(1), result_);
    out.estimates.clear();
    for (const auto& c : result_.candidates)
      out.estimates.push_back({c.obj_id,
                               c.R_m2c,
                               c.t_m2c_mm,
                               c.score,
                               c.rank_px,
                               c.fit_rank,
                               c.grasp_visibility,
                               {{"fit_rank", c.fit_rank},
                                {"coverage", c.coverage},
                                {"inlier_fraction", c.inlier_fraction},
                                {"fit_cost_px", c.fit_cost_px},
                                {"ambiguous", c.ambiguous ? 1.0 : 0.0},
                                {"has_alternative", c.has_alternative ? 1.0 : 0.0},
                                {"alternative_rank", c.alternative_rank},
                                {"alternative_differs", c.alternative_differs},
                                {"alternative_support", c.alternative_support}},
                               c.ambiguous});
    out.times = result_.times;
    out.views_searched = result_.views_searched;
    out.evaluated = result_.hypotheses;
    out.escalated = result_.escalated;
    out.coarse_hypotheses.clear();
    out.fitted_hypotheses.clear();
    for (const auto& h : result_.trace) {
      out.coarse_hypotheses.push_back({h.obj_id, h.R_coarse, h.t_coarse_mm, 0, h.search_cost_px, h.fit_rank, 1, {}});
      out.fitted_hypotheses.push_back({h.obj_id,
                                       h.R_fitted,
                                       h.t_fitted_mm,
                                       0,
                                       h.search_cost_px,
                                       h.fit_rank,
                                       1,
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
  std::optional<vision::ShadingAgreement> shading(const vision::MfcFrames& frames, int obj_id, const cv::Matx33d& R,
                                                  const cv::Vec3d& t_mm) override {
    if (!shading_) {
      // A renderer of its own (the pipeline's keeps its camera and meshes), made on first use in
      // this thread, with the parts' meshes from their template files.
      shading_renderer_ = std::make_unique<vision::MfcRenderer>(camera_);
      for (const auto& file : templates_) {
        const vision::TemplateDatabase db = vision::load_template_database(file);
        shading_models_[db.obj_id] = vision::pose_model(shading_renderer_->add_mesh(db.mesh), db.mesh);
      }
      shading_ = std::make_unique<vision::ShadingCheck>(*shading_renderer_);
    }
    const auto it = shading_models_.find(obj_id);
    if (it == shading_models_.end()) return std::nullopt;
    return shading_->compare(frames, camera_.camera, it->second, vision::RigidTransform{R, t_mm});
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
  vision::BinFloor floor_;  // the configured floor (its tolerance); set_floor_mm moves it
  vision::PipelineResult result_;
  double setup_s_ = 0;
  vision::CameraConfig camera_;
  std::vector<std::filesystem::path> templates_;
  std::unique_ptr<vision::MfcRenderer> shading_renderer_;
  std::map<int, vision::PoseModel> shading_models_;  // by obj_id
  std::unique_ptr<vision::ShadingCheck> shading_;
};

}  // namespace

std::unique_ptr<Detector> make_pipeline_detector(
    const std::string& name, vision::PipelineConfig::Cost cost, const vision::CameraConfig& camera,
    const std::vector<std::filesystem::path>& templates, int threads, int max_candidates,
    const std::vector<double>& distances_mm, int refine_candidates, bool fit_hypotheses,
    const std::vector<std::string>& settings, const std::vector<std::pair<int, vision::GraspFeature>>& grasp_features) {
  return std::make_unique<PipelineDetector>(name, cost, camera, templates, threads, max_candidates, distances_mm,
                                            refine_candidates, fit_hypotheses, settings, grasp_features);
}

void apply_eval_setting(vision::PipelineConfig& c, const std::string& setting) {
  // The bin floor's distance is the cell's geometry, not a pipeline parameter (the daemon takes it
  // from pick.bin_floor_distance_mm); the evaluation sets it per dataset (--floor).
  const std::string floor_key = "floor_distance_mm=";
  if (setting.rfind(floor_key, 0) == 0) {
    c.floor.distance_mm = mfcd::tools::parse_double("floor_distance_mm", setting.substr(floor_key.size()));
    c.floor.validate();
    return;
  }
  vision::apply_pipeline_setting(c, setting);
}

}  // namespace mfcd::eval
