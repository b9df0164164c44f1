// FDCM, OCM and CM: the bin-picking pipeline with each matching cost.
#include "tools/eval/detectors.hpp"

#include <chrono>

namespace mfcd::eval {

namespace {

class PipelineDetector final : public Detector {
 public:
  PipelineDetector(std::string name, vision::PipelineConfig::Cost cost, const vision::CameraConfig& camera,
                   const std::vector<std::filesystem::path>& templates, int threads, int max_candidates,
                   const std::vector<double>& distances_mm, int refine_candidates, bool fit_hypotheses)
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
    pipeline_ = std::make_unique<vision::BinPickingPipeline>(camera, pc);
    setup_s_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  std::string name() const override { return name_; }
  void detect(const vision::MfcFrames& frames, int obj_id, Detection& out) override {
    // No deadline: the evaluation measures the full search of every method.
    pipeline_->process(frames, obj_id, std::chrono::steady_clock::now() + std::chrono::hours(1), result_);
    out.estimates.clear();
    for (const auto& c : result_.candidates) out.estimates.push_back({c.obj_id, c.R_m2c, c.t_m2c_mm, c.score, c.rank_px, c.fit_rank});
    out.times = result_.times;
  }
  std::optional<vision::PoseScore> score_pose(int obj_id, const cv::Matx33d& R, const cv::Vec3d& t_mm) override {
    if (cost_ != vision::PipelineConfig::Cost::fdcm) return std::nullopt;
    return pipeline_->score_pose(obj_id, R, t_mm);
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
                                                 int refine_candidates, bool fit_hypotheses) {
  return std::make_unique<PipelineDetector>(name, cost, camera, templates, threads, max_candidates, distances_mm,
                                            refine_candidates, fit_hypotheses);
}

}  // namespace mfcd::eval
