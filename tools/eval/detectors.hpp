#pragma once
// The detectors mfc-eval compares, behind one interface: the bin-picking pipeline with each
// matching cost (FDCM, OCM, CM: the same line-search hypotheses, paper Table 1) and LINE-2D
// (OpenCV contrib cv::linemod, a peer method trained on the same template views).

#include "vision/camera/camera.hpp"
#include "vision/camera/mfc_frames.hpp"
#include "vision/pipeline/bin_picking_pipeline.hpp"
#include "vision/pose/shading_check.hpp"

#include <opencv2/core.hpp>

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace mfcd::eval {

struct Estimate {
  int obj_id = 0;
  cv::Matx33d R = cv::Matx33d::eye();
  cv::Vec3d t_mm{0, 0, 0};
  double score = 0;
  double rank_px = 0;           // pipeline detectors: the search's ranking measure (PoseCandidate::rank_px)
  double rank = 0;              // pipeline detectors: the fitted hypothesis' rank (PoseCandidate::fit_rank)
  double grasp_visibility = 1;  // pipeline detectors: PoseCandidate::grasp_visibility
  // Traced hypotheses (--set trace=1): the measures the rank is made of, by name (HypothesisTrace).
  std::vector<std::pair<std::string, double>> measures;
  bool ambiguous = false;  // pipeline detectors: PoseCandidate::ambiguous
};

struct Detection {
  std::vector<Estimate> estimates;  // best first
  vision::StageTimes times;         // stages the detector has; total_ms always set
  int views_searched = 0;           // pipeline detectors: template views the search visited
  uint64_t evaluated = 0;           // pipeline detectors: hypotheses the search evaluated
  bool escalated = false;           // pipeline detectors: the wide search ran (PipelineConfig::escalate_below)
  // Pipeline detectors with PipelineConfig::trace (--set trace=1): every fitted hypothesis,
  // before (coarse) and after the fit, in search order.
  std::vector<Estimate> coarse_hypotheses, fitted_hypotheses;
};

class Detector {
 public:
  virtual ~Detector() = default;
  virtual std::string name() const = 0;
  // obj_id = 0: every loaded part type (best pick); otherwise that type only (the recipe).
  virtual void detect(const vision::MfcFrames& frames, int obj_id, Detection& out) = 0;
  // The bin floor's distance (mm, along the optical axis; 0: not known) for the next detect()s:
  // the scene's own when the dataset says where its bin stands (--floor scene).
  virtual void set_floor_mm(double distance_mm) = 0;
  // How the last detect()'s image scores a given pose (the truth), measured as the detector
  // ranks its own hypotheses; detectors without such a measure return nothing.
  virtual std::optional<vision::PoseScore> score_pose(int /*obj_id*/, const cv::Matx33d& /*R*/,
                                                      const cv::Vec3d& /*t_mm*/) {
    return std::nullopt;
  }
  // How the flashes' shares of light at a pose of part obj_id agree with `frames`'
  // (vision/pose/shading_check.hpp); detectors without the part's mesh return nothing.
  virtual std::optional<vision::ShadingAgreement> shading(const vision::MfcFrames& /*frames*/, int /*obj_id*/,
                                                          const cv::Matx33d& /*R*/, const cv::Vec3d& /*t_mm*/) {
    return std::nullopt;
  }
  // Whether part obj_id at a pose shows a grasp feature, on top and facing the camera, on the
  // last detect()'s image (vision/pose/grasp_visibility.hpp); detectors without depth edges
  // return nothing.
  virtual std::optional<vision::GraspVisibility> grasp_visibility(int /*obj_id*/, const cv::Matx33d& /*R*/,
                                                                  const cv::Vec3d& /*t_mm*/,
                                                                  const vision::GraspFeature& /*feature*/) {
    return std::nullopt;
  }
  // The last detect()'s depth edges (dimmed) with the given poses of part obj_id drawn on them
  // (mfc-eval --overlay); detectors without edge images return nothing.
  struct DrawnPose {
    cv::Matx33d R = cv::Matx33d::eye();
    cv::Vec3d t_mm{0, 0, 0};
    cv::Scalar colour;
  };
  virtual std::optional<cv::Mat3b> overlay(int /*obj_id*/, const std::vector<DrawnPose>& /*poses*/) const {
    return std::nullopt;
  }
  // Seconds spent preparing (loading templates, training).
  virtual double setup_seconds() const = 0;
};

// FDCM / OCM / CM through BinPickingPipeline; `distances_mm` and `refine_candidates` as in
// PipelineConfig (refine_candidates < 0: the pipeline's default).
// `fit_hypotheses` as PipelineConfig's (the FDCM cost only); `name` is the method's name;
// `settings` ("key=value", apply_pipeline_setting) are applied last; `grasp_features` as
// PipelineConfig's (the estimates' grasp_visibility).
std::unique_ptr<Detector> make_pipeline_detector(
    const std::string& name, vision::PipelineConfig::Cost cost, const vision::CameraConfig& camera,
    const std::vector<std::filesystem::path>& templates, int threads, int max_candidates,
    const std::vector<double>& distances_mm, int refine_candidates, bool fit_hypotheses,
    const std::vector<std::string>& settings = {},
    const std::vector<std::pair<int, vision::GraspFeature>>& grasp_features = {});

// One "key=value" of mfc-eval --set: a parameter of vision/pipeline/pipeline_parameters.hpp, or
// floor_distance_mm (the bin floor, mm; 0 = not known). Throws std::invalid_argument naming the
// key or value it refuses.
void apply_eval_setting(vision::PipelineConfig& config, const std::string& setting);

struct Line2dOptions {
  double inplane_step_deg = 15;      // in-plane rotations trained per view (LINE-2D is not rotation invariant)
  int view_stride = 1;               // use every n-th template view
  float min_similarity = 60;         // cv::linemod match threshold, percent
  std::vector<double> distances_mm;  // trained at the scale of each (as the pipeline searches); empty = 1
  vision::BinFloor floor;            // poses below a known floor are moved onto it (as the pipeline's unfitted ones)
};
// LINE-2D on the max image (the per-pixel maximum of the flash images): for every template
// view of every part, the part rendered alone at the view's pose by MfcRenderer, turned in the
// image plane about the part centre's image, with its silhouette as the mask.
std::unique_ptr<Detector> make_line2d_detector(const vision::CameraConfig& camera,
                                               const std::vector<std::filesystem::path>& templates,
                                               const Line2dOptions& options, int max_candidates);

}  // namespace mfcd::eval
