#pragma once
// The whole vision path of one pick cycle, composed from the paper's stages:
// flash images -> depth edges (4.2) -> lines (3.3) -> DT3/IDT3 (3.4-3.5) -> FDCM search over
// every template of every loaded part (3.6, 4.3) -> coarse 3-D pose (4.4) -> multi-view
// refinement (4.5) -> ranked pick candidates. The daemon's vision worker owns one instance and
// calls process() once per FrameSet.
//
// Buffers are sized at construction (image size, candidate capacity); process() then reuses
// them. Not thread-safe: one pipeline per worker thread (it owns an EGL context for rendering
// model edges, which is bound to the thread that made it).

#include "vision/camera/camera.hpp"
#include "vision/camera/mfc_frames.hpp"
#include "vision/edges/depth_edges.hpp"
#include "vision/pipeline/confidence_fitted.hpp"
#include "vision/pose/bin_floor.hpp"
#include "vision/pose/grasp_visibility.hpp"
#include "vision/pose/gripper_check.hpp"

#include <opencv2/core.hpp>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace mfcd::vision {

// The pipeline's settings. Every scalar here is a parameter of the table in
// pipeline_parameters.hpp (key = field name, with its range, unit and meaning; its default is the
// initializer below); docs/tuning-log.md says why each has its value. The rest are the cycle's
// inputs: template files, distances, the floor's plane, grasp features, the matching cost.
struct PipelineConfig {
  // Matching cost: FDCM (the product), or the paper's baselines OCM and CM scored on the same
  // hypotheses (the evaluation's Table 1).
  enum class Cost { fdcm, ocm, cm };
  Cost cost = Cost::fdcm;
  std::vector<std::filesystem::path> template_files;  // *.tdb, one per part type (mfc-teach)
  std::vector<double> distances_mm;                   // hypothesised part distances, mm; empty = the templates' own
  DepthEdgeParams depth_edges;                        // edges_* parameters
  // The bin floor's plane (distance 0: not known, no check); floor.tolerance_mm is the parameter
  // floor_tolerance_mm.
  BinFloor floor;
  // Grasp features per part type (obj_id, feature; the best one counts) for
  // PoseCandidate::grasp_visibility; a part type without any keeps 1.
  std::vector<std::pair<int, GraspFeature>> grasp_features;

  // FDCM search (paper Sec. 3.6, 4.3): 1-D line search over coarse then fine views.
  double max_cost_px = 10.0;                // px, mean directional chamfer cost of a hit
  int search_downsample = 3;                // image reduction of the search (1..4)
  bool search_polarity = true;              // FDCM only: 2q oriented channels over 2 pi
  double search_polarity_penalty_px = 6.0;  // px; infinity: such an edge is as good as none
  int template_guides = 3;
  int query_guides = 60;
  // A query line more than this times a template's longest guide is not the guide's edge: an
  // edge of the part is at most as long as the template's line times the taught distance over
  // the part's (1.5: a third nearer than the teach distance) and, fragmented by occlusion and
  // noise, usually shorter. So in a bin of large and small parts the small ones slide along lines
  // of their own size, not only along the large parts' outlines.
  double max_query_to_guide = 1.5;
  double min_guide_overlap = 0.75;  // of the shorter line
  int slide_step = 2;               // px at the search's resolution
  int view_stride = 4;              // 1 = every view in one stage
  int coarse_seeds = 6;             // per part type searched; 0 = the coarse stage only
  int keep_per_view = 1;
  int keep_separation_px = 8;
  // Off: the shared bound makes the hits depend on the threads' timing (docs/fdcm.md), and a
  // cycle must give the same candidates on any thread count and load (a snapshot replays).
  bool share_search_bound = false;
  // Search rounds: FDCM only (the baselines and evaluation tools search once); a round starts
  // only when the deadline leaves it the time the last one took.
  static constexpr int kMaxSearchRounds = 4;
  int search_rounds = 1;
  int round_hypotheses = 16;
  int round_erase_px = 2;  // px around the best candidates' points taken out of a later round
  // Escalation (FDCM with the fit only): the wide search searches every view with
  // escalate_query_guides guides and two placements per view at least 40 px apart; like a round it
  // starts only when the deadline leaves it the time the last escalation took.
  double escalate_below = 0.08;  // fitted rank; 0 = off
  int escalate_query_guides = 120;
  int escalate_hypotheses = 150;
  int escalate_placements_per_view = 2;
  int escalate_separation_px = 40;   // full-resolution px between one view's placements
  double escalate_max_cost_px = 14;  // px; 0 = max_cost_px

  // 3-D pose (Sec. 4.4): hypotheses fitted in 6-DoF (TemplatePoseFit) and ranked by
  // fit score - unexplained_weight x (unexplained edge share) + evidence_weight x ln(found / 300).
  bool fit_hypotheses = true;
  int fit_candidates = 48;
  // Hypotheses fitted in addition for each part type a cycle searches beyond the first: chamfer
  // costs do not compare across templates (a template of a few straight lines lies cheaply on any
  // bin's straight edges), so with a fixed count the hits of such a type take the fits the others'
  // right placements need. The deadline still cuts the fit short.
  int fit_candidates_per_type = 4;
  double fit_score_gate_px = 4.0;   // px (TemplateFitParams::score_gate_px)
  double fit_inlier_cost_px = 2.0;  // px (TemplateFitParams::inlier_cost_px), <= the gate
  bool edge_polarity = true;        // the fit's pairing by the depth edges' shadow side
  double unexplained_weight = 0.3;
  double evidence_weight = 0.06;
  // The checks of the leading fitted hypotheses, each 0 = off: rescoring with every point of the
  // view (the fit uses at most 160), depth starts (depth_start_mm further and nearer), the
  // turned-over comparison (TemplatePoseFit::compare), floor starts (with a known floor).
  int rescore_hypotheses = 12;
  int depth_starts = 6;
  double depth_start_mm = 2;  // mm along the line of sight
  int flip_checks = 6;
  int floor_starts = 6;
  double floor_start_height_mm = 30;         // mm above the floor a hypothesis may hover and start again from it
  double floor_start_min_score_ratio = 0.8;  // of the free fit's score, for the floor start's fit to be kept

  // Candidates and refinement (Sec. 4.5, one view).
  int max_candidates = 8;             // best first
  double candidate_overlap = 0.3;     // search boxes overlapping more (IoU) are one part
  double alternative_min_differ = 0;  // PoseCandidate::alternative_*
  // A candidate whose edges favour it over its alternative's by less than this share of the
  // points where the two differ is ambiguous (PoseCandidate::ambiguous).
  double ambiguous_support = 0.1;
  // PoseCandidate::score of a fitted candidate: the probability that its pose is right.
  ConfidenceModel confidence = kFittedConfidence;
  // The candidates' poses polished with the templates' edge offset profiles; ranking is without it.
  bool edge_offset_correction = true;
  int refine_candidates = 0;   // render-based PoseRefiner on the best n; 0 = fitted pose kept
  int refine_iterations = 10;  // outer ICP iterations per refined candidate; 0 = no refinement

  // Threads of every stage of a cycle; 0 = the calling thread's OpenMP setting.
  int threads = 0;
  // Diagnostics (mfc-eval): every fitted hypothesis also in PipelineResult::trace. Allocates per
  // cycle; not a cell setting.
  bool trace = false;
};

struct PoseCandidate {
  int obj_id = 0;                          // BOP object id of the part type (from its .tdb)
  std::string part;                        // part name from the .tdb
  int view = -1;                           // template view (out-of-plane rotation) that matched
  cv::Matx33d R_m2c = cv::Matx33d::eye();  // model -> camera rotation
  cv::Vec3d t_m2c_mm{0, 0, 0};             // model origin in the camera frame, mm
  // 0..1: the estimated probability that the pose is right (within 5 mm and 10 degrees of a true
  // pose; PipelineConfig::confidence of evidence()); without the fit (the paper's baselines)
  // 1 / (1 + c / 2 px) of the search cost c with the unexplained-edge penalty, a rank only.
  double score = 0;
  double cost_px = 0;          // mean directional chamfer cost at the final pose
  double coverage = 0;         // fraction of image edges inside the part's outline it explains
  double rank_px = 0;          // the search's ranking measure: cost_px + the unexplained-edge penalty
  double fit_rank = 0;         // the rank after TemplatePoseFit (fit score less unexplained edges)
  double inlier_fraction = 0;  // the fit's share of view points within its inlier cost
  double fit_cost_px = 0;      // the fit's mean directional cost, px
  bool refined = false;        // false: coarse pose only (refinement skipped or failed)
  // 0..1: how clearly its best grasp feature is on top and facing the camera at the final pose
  // (vision/pose/grasp_visibility.hpp); 1 when its part type has no grasp feature configured.
  double grasp_visibility = 1;
  cv::Rect2d box;  // image bounding box of the matched template
  // What the edges had to tell this pose from: the best-ranked other fitted hypothesis of the
  // part at its place (search boxes overlapping as in the candidates' suppression) that is
  // another answer: its centre kDistinctPositionMm or more away, or its orientation
  // kDistinctRotationDeg or more over the part's exact symmetries (confidence.hpp), and at
  // least alternative_min_differ of the two poses' edge points more than 3 px from any point
  // of the other. A twin whose edges are this pose's own is an alternative the edges cannot
  // tell apart. None: no such hypothesis was fitted, or the deadline had passed.
  bool has_alternative = false;
  double alternative_rank = 0;     // its fit_rank
  double alternative_differs = 0;  // share of the two poses' edge points that differ
  // On the differing points: the share on image edges of this pose's less the alternative's.
  double alternative_support = 0;
  // The edges do not tell this pose from its alternative: alternative_support below
  // PipelineConfig::ambiguous_support. The cell's pick passes it over (pick.skip_ambiguous).
  bool ambiguous = false;

  PoseEvidence evidence() const;  // the measures above, as the confidence model takes them
};

struct StageTimes {
  double edges_ms = 0, lines_ms = 0, distance_ms = 0, search_ms = 0, pose_ms = 0, refine_ms = 0, total_ms = 0;
};

// One hypothesis of the cycle as the search found it and as the fit left it (PipelineConfig::trace).
struct HypothesisTrace {
  int obj_id = 0;
  int round = 1;  // the search round that found it (PipelineConfig::search_rounds); 0: the
                  // escalation's wide search (PipelineConfig::escalate_below)
  int search_view = -1, fitted_view = -1;
  double search_cost_px = 0;  // mean directional chamfer cost of the search hit
  double coverage = 0;        // explained-edge fraction at the search hit
  cv::Matx33d R_coarse = cv::Matx33d::eye(), R_fitted = cv::Matx33d::eye();  // model -> camera
  cv::Vec3d t_coarse_mm{0, 0, 0}, t_fitted_mm{0, 0, 0};
  double fit_rank = -1;  // as PoseCandidate::fit_rank; -1 = fit refused
  // The fit's measures at the fitted pose (TemplateFitResult), what fit_rank is made of.
  double fit_score = 0, fit_coverage = 0, inlier_fraction = 0, mean_cost_px = 0;
  double view_points = 0;  // the fitted view's edge points at the fitted distance
};

struct PipelineResult {
  std::vector<PoseCandidate> candidates;  // best first; capacity reserved once
  StageTimes times;
  // The deadline cut a stage short (search views, fits, the leaders' checks, a candidate's
  // alternative or edge-offset fit, refinement): best-so-far result. Not degraded, the result is
  // the one an unlimited deadline gives, except that a later round or the escalation may have
  // been skipped for time (they only add candidates; PipelineResult::rounds, escalated).
  bool degraded = false;
  int edge_pixels = 0;
  int query_lines = 0;
  uint64_t hypotheses = 0;             // FDCM hypotheses evaluated by the search, all rounds
  int views_searched = 0;              // template views searched, all rounds (fewer than loaded when degraded)
  int rounds = 1;                      // search rounds run (PipelineConfig::search_rounds; fewer near the deadline)
  bool escalated = false;              // the wide search ran (PipelineConfig::escalate_below)
  std::vector<HypothesisTrace> trace;  // PipelineConfig::trace only: every fitted hypothesis, search order,
                                       // before the turned-over check
};

// How the last processed image scores a given pose of a part, measured the way the search
// scores its own hypotheses (for the evaluation: was a miss the search's or the cost's?).
struct PoseScore {
  int view = -1;              // nearest template view (symmetry-aware)
  double view_angle_deg = 0;  // rotation between the given pose and that view's coarse pose
  double cost_px = 0;         // mean directional chamfer cost after the local fit (fit_distance)
  double coverage = 0;        // fraction of image edges inside the outline the view explains
  double rank_px = 0;         // cost_px + unexplained-edge penalty: compare with PoseCandidate::rank_px
  double fit_score = 0;       // TemplatePoseFit score from the view's coarse pose: compare with PoseCandidate::score
  double exact_score = 0;     // the same rank at the given pose itself, unfitted (do the edges prefer it?)
};

class BinPickingPipeline {
 public:
  // Loads and checks every template file against `camera` (refused with the file and the
  // reason on mismatch or corruption). Throws std::runtime_error.
  BinPickingPipeline(const CameraConfig& camera, PipelineConfig config);
  ~BinPickingPipeline();
  BinPickingPipeline(const BinPickingPipeline&) = delete;
  BinPickingPipeline& operator=(const BinPickingPipeline&) = delete;

  // obj_id = 0 searches every loaded part type, otherwise only that one (the PLC's recipe).
  // Stages that would pass `deadline` are shortened (fewer refinement iterations, then no
  // refinement) and the result is flagged degraded; it never blocks past the deadline by
  // more than one stage.
  void process(const MfcFrames& frames, int obj_id, std::chrono::steady_clock::time_point deadline,
               PipelineResult& out);

  // The pose (model -> camera) of part obj_id scored on the last process()'s image (FDCM cost
  // only). Throws std::invalid_argument for an unknown obj_id or another cost.
  PoseScore score_pose(int obj_id, const cv::Matx33d& R_m2c, const cv::Vec3d& t_m2c_mm);

  // Whether part obj_id at a pose (model -> camera) shows a grasp feature, on top and facing
  // the camera, on the last process()'s image (vision/pose/grasp_visibility.hpp). Throws
  // std::invalid_argument for an unknown obj_id.
  GraspVisibility grasp_visibility(int obj_id, const cv::Matx33d& R_m2c, const cv::Vec3d& t_m2c_mm,
                                   const GraspFeature& feature);

  // The bin floor of the next cycles (a cell whose bins stand at different heights, per recipe).
  // Its tolerance_mm replaces floor_tolerance_mm's. Throws std::invalid_argument naming the field
  // (BinFloor::validate); the floor is then unchanged. Not during process().
  void set_floor(const BinFloor& floor);

  // The gripper check (paper Sec. 4.6, vision/pose/gripper_check.hpp) rendering with this
  // pipeline's renderer, which is made now if no refinement has yet (in the calling thread, whose
  // GL context it binds: the thread of process()). The check must not outlive the pipeline.
  // Throws std::invalid_argument naming the parameter.
  std::unique_ptr<GripperCheck> make_gripper_check(const GripperCheckParams& params);
  // Part obj_id as that renderer knows it (for GripperCheck::check). Throws std::invalid_argument
  // for an unknown obj_id.
  PoseModel pose_model_of(int obj_id);

  // Part types loaded, as (obj_id, name).
  std::vector<std::pair<int, std::string>> parts() const;
  const CameraConfig& camera() const;
  // The depth edges of the last process() (for snapshots and overlays).
  const DepthEdges& last_edges() const;

  // Draws part obj_id at a pose (model -> camera) onto `image`: the model points of its nearest
  // template view (symmetry-aware), projected, i.e. the edges the fit scores that pose by.
  // Throws std::invalid_argument for an unknown obj_id.
  void draw_pose(cv::Mat3b& image, int obj_id, const cv::Matx33d& R_m2c, const cv::Vec3d& t_m2c_mm,
                 const cv::Scalar& colour) const;

  // The pipeline's state, which its stages share: defined in the internal
  // vision/pipeline/pipeline_state.hpp (an incomplete type for every user of this header).
  struct Impl;

 private:
  friend class SecondLook;  // fits poses to two pipelines' images at once (second_look.hpp)
  std::unique_ptr<Impl> impl_;
};

// Draws the candidates (model outline at the pose, index, score) over a grey image.
cv::Mat3b draw_candidates(const cv::Mat1b& image, const PipelineResult& result, const CameraConfig& camera);

}  // namespace mfcd::vision
