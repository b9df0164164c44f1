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
#include "vision/pose/bin_floor.hpp"
#include "vision/pose/grasp_visibility.hpp"

#include <opencv2/core.hpp>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace mfcd::vision {

struct PipelineConfig {
  // Matching cost: FDCM (the product), or the paper's baselines OCM and CM scored on the same
  // hypotheses (for the evaluation's Table 1).
  enum class Cost { fdcm, ocm, cm };
  Cost cost = Cost::fdcm;
  std::vector<std::filesystem::path> template_files;  // *.tdb, one per part type (mfc-teach)
  int max_candidates = 8;          // pick candidates kept per cycle, best first
  // Search threshold, px (mean directional chamfer cost). A part between template views reaches
  // 3-4 px alone and 5-7 px in a full bin; the hypothesis fit decides, so this only bounds the
  // search. A part with few views (the wheel's 5-fold symmetry leaves it 60 of 300) can lie far
  // from all of them: at 8 px its truth was sometimes not among the hits at all. Measured at 8 /
  // 9 / 10 / 12 (dev sets, mfc-sim seeds 7, 13, 19, 283 trials; bench set, 119; capped-occlusion
  // set, 116): 81 / 80 / 80 / 80, 30 / 27 / 28 / 28, 17 / 16 / 16 / 16 failures, none broken at 10;
  // median detection +1.5 ms (docs/pose-experiments.md, "Session 12: the search threshold").
  double max_cost_px = 10.0;
  std::vector<double> distances_mm;  // hypothesised part distances; empty = the templates' own
  // 1-D line search (paper Sec. 4.4): each template's longest `template_guides` lines are slid
  // along the query's longest `query_guides` lines of the same orientation.
  int template_guides = 3;
  int query_guides = 60;   // long clutter (rods, other parts) fills the first 30 in a full bin
  double min_guide_overlap = 0.75;  // of the shorter line (LineSearchParams::minOverlap)
  // Views coarse to fine: every `view_stride`-th view first, then the not yet searched views
  // near (out-of-plane) the views of the best coarse_seeds x (parts searched) coarse hits. 1 =
  // every view in one stage. coarse_seeds = 0: the coarse stage only (the hypothesis fit moves
  // between views). Measured on the dev set (mfc-sim seed 7, 93 trials): stride 4 with 6 seeds
  // searches 67 of 155 views on average for one failure more (32 vs 31).
  int view_stride = 4;
  int coarse_seeds = 6;
  int keep_per_view = 1;            // best placements kept per view, more than keep_separation_px apart
  int keep_separation_px = 8;
  // The search (query lines, DT3, IDT3, templated lines, fit_distance) runs on the image reduced
  // by this factor (1..4; reduceQuery); hypotheses are then fitted at full resolution. The search
  // only has to put the truth among the fit's hypotheses, and at a third of the resolution
  // IDT3 is 4 MB instead of 37 (it stays in cache) and lines are a third as long. Measured on
  // three dev sets (mfc-sim seeds 7, 13, 19; 283 trials): 98 failures at 1 (slide_step 4), 90
  // at 3 (slide_step 2); median detection 130 -> 70 ms, breaker 220 -> 100 ms (runs one after
  // the other on this shared machine).
  int search_downsample = 3;
  int slide_step = 2;               // search px between slide positions, then the best refined (LineSearchParams)
  // Searches abandon a placement as soon as it cannot be among the fit_candidates best hits of
  // the cycle so far (a bound shared by the search threads). With slide_step 1 exactly the same
  // hits as without; with coarser steps a slide whose coarse best lies above the bound is no
  // longer refined around it (on the 93-trial dev set no result changed; search 20 % faster).
  bool share_search_bound = true;
  // Hypotheses (distinct best search hits) fitted in 6-DoF with their template's model points
  // and ranked by the fitted score (TemplatePoseFit); false = ranked by the search cost.
  int fit_candidates = 48;
  // The best this many fitted hypotheses are scored again with every point of their view (the fit
  // uses at most 160, evenly subsampled) and ranked by that, before the checks below, whose new
  // fits of them (floor starts, turned over) are then scored the same way. The scores of competing
  // poses often differ by a few hundredths, about the subsample's own scatter. Measured on the
  // capped, bench and three dev sets (1241 trials): failures 277 -> 267 with the ranking alone
  // (24 or 48: the same), 257 with the checks' fits scored alike; instances among the top k
  // 1175 -> 1198; median detection of the bench set 59 -> 68 ms (docs/pose.md "Rescoring with
  // every point"). 0 = off.
  int rescore_hypotheses = 12;
  // The best this many fitted hypotheses are also fitted turned over (by 180 degrees about each
  // model axis that is not a symmetry) and, for an N-fold symmetry about z (N >= 3), turned about z
  // by +-0.4 of the period, and replaced by the turned pose when the edges where the two differ
  // favour it (TemplatePoseFit::compare; docs/pose.md "Turned-over check"). 0 = off.
  int flip_checks = 6;
  // Evidence: the fitted rank gains evidence_weight x ln(found / 300), found = the matched view's
  // edge points at the fitted distance times the fit's inlier fraction. A flat part seen edge-on
  // is two long parallel lines, and rods or the rim of a wheel give it as large a share of its
  // points as a part lying flat finds of its much longer outline; the count of points found is
  // the evidence. (Counting all the view's points instead, found or not, favoured views with
  // more edges: a lone T-nut came out 12 degrees off.) Measured on two dev sets (mfc-sim seeds 7
  // and 13, 191 trials): 67 failures at 0, 65 at 0.06; the lone-part control unchanged.
  double evidence_weight = 0.06;
  // The hypothesis fit's scoring (TemplateFitParams::score_gate_px, inlier_cost_px) and the
  // weight of the image edges inside a fitted outline that it leaves unexplained (all of them
  // unexplained lowers the rank by this much).
  double fit_score_gate_px = 4.0;
  double fit_inlier_cost_px = 2.0;
  double unexplained_weight = 0.3;
  bool fit_hypotheses = true;
  // Edge polarity: the fit pairs a template point only with an image edge whose near (occluding)
  // side is the part's (the depth edges' shadow side; TemplatePoseFit::prepare). Wrong hypotheses
  // lose about half their score, the truth about 6 %. Measured (docs/pose.md "Edge polarity in
  // the fit"): instances found among the top k 41 more, 21 fewer over the dev, capped and bench
  // sets; best-pick failures 162 -> 159. false = undirected, as before.
  bool edge_polarity = true;
  // Each pick candidate's fitted pose is polished once more with the templates' edge offset
  // profiles (TemplateFitParams::edge_offset_correction): parts turned in the image are otherwise
  // reported up to ~2 mm too near the camera (docs/pose.md, "Edge offset profiles"). The
  // hypotheses are ranked without it either way.
  bool edge_offset_correction = true;
  // Edge polarity in the FDCM search (docs/fdcm.md "Search with edge polarity"): query and
  // template lines are oriented by their shadow side and DT3/IDT3 have 2q channels over 2 pi, so
  // a template line only matches image edges whose near side is on the same side. FDCM only
  // (the baselines CM and OCM stay the paper's). false = undirected channels, as before.
  bool search_polarity = true;
  // What an image edge of the other polarity costs the search beyond its undirected orientation
  // difference, px (Dt3Params::polarityPenalty; infinity: such an edge is as good as none). Parts
  // in a bin touch: where a lower part's outline meets the upper one's, the depth edge there is
  // the upper part's, and the lower part's template sees it reversed. Measured (docs/fdcm.md
  // "Search with edge polarity"), failures over the capped, bench and three dev sets: 283
  // undirected, 286 at infinity, 277 at 6 px; 3 and 10 px on three of the sets: 147 and 144 against 140.
  double search_polarity_penalty_px = 6.0;
  // The bin floor (BinFloor): no part reaches below it. A fitted hypothesis reaching more than
  // its tolerance below is dropped; an unfitted one (the baselines) is slid onto the floor. Not
  // known by default (distance 0): no check. Measured on three dev sets (mfc-sim seeds 7, 13, 19;
  // 283 trials; floor at 300 mm) and the bench set (119 trials): 88 and 35 failures without, 85
  // and 33 with (docs/pose.md "The bin floor"; 81 and 30 with the floor starts below).
  BinFloor floor;
  // With a known floor, the best this many fitted hypotheses whose lowest point lies a few to
  // 30 mm above it are fitted again from the pose slid down onto the floor, and take that fit when
  // it scores at least 0.8 of theirs (docs/pose.md "The bin floor"). 0 = off.
  int floor_starts = 6;
  // Depth starts: the best this many fitted hypotheses are fitted again from their pose moved
  // depth_start_mm along the line of sight, once further and once nearer, and take a new fit that
  // ranks higher. The fit settles on the depth nearest its start, and the depth (a part's image
  // scale) is what one view measures worst: the fit of a T-nut on its side stopped 5 mm too near,
  // 6 degrees off, at rank -0.02 where its true pose ranks 0.14. Measured on the capped, bench and
  // three dev sets (1241 trials, docs/pose.md "Depth starts"): 246 failures without, 242 with 6
  // starts at 2 mm (four fixed, none broken). 0 = off.
  int depth_starts = 6;
  double depth_start_mm = 2;
  // Search rounds: each view keeps only its best placement, so the hypotheses gather on the
  // instance that matches best, and a second instance of the type is often not among them
  // (docs/pose.md "Search rounds"). A later round takes out of the query (its lines and
  // directional edge map) the image edges that the best candidates so far explain (round k: the
  // best k - 1 distinct ones), searches again and fits its best `round_hypotheses` new hits, ranked
  // with the others. It starts only when the deadline leaves it the time the last one took, and
  // costs about as much as the first search plus that many fits. 1..kMaxSearchRounds; 1 = one
  // search. FDCM only (the baselines, evaluation tools, always search once).
  static constexpr int kMaxSearchRounds = 4;
  int search_rounds = 1;
  int round_hypotheses = 16;
  // Escalation: when the first search's best fitted hypothesis ranks below `escalate_below` (the
  // cycle has nothing a cell would pick: config pick.min_score is 0.08-0.1, and 0.08, the lower,
  // is the default), the search runs again wide: every view of the part types, escalate_query_guides query guides, two placements per
  // view at least 40 px apart, and escalate_hypotheses hypotheses fitted and ranked with the
  // first search's. With the shipped search most failed trials have no correct hypothesis fitted
  // at all (capped-occlusion set: a correct one in 213 of 238 trials, against 230 with the wide
  // search), but in every cycle the wide search would cost 3-4 times the cycle (docs/pose.md
  // "Escalation": failures 80 -> 71 on the dev sets, 33 -> 27 capped). Like a later round it
  // starts only when the deadline leaves it the time the last escalation took, and skipping it
  // does not degrade the cycle. 0 = off. FDCM with the hypothesis fit only. (0.1 before edge
  // polarity, which lowers every fit score a little: at 0.1 the bench set then escalated 78
  // cycles, at 0.08 66, with the same failures on the dev, capped and bench sets.)
  double escalate_below = 0.08;
  int escalate_query_guides = 120;
  int escalate_hypotheses = 150;
  // The wide search's threshold (max_cost_px for it; 0 = max_cost_px). The wheel (60 views for its
  // 5-fold symmetry) can lie far from all its views: with the first search's 10 px a wheel 27 %
  // hidden had 7 hits in the wide search, none on it, while its truth fitted to rank 0.25 against
  // the pick's -0.18. Measured on the capped, bench and three dev sets (1241 trials, session 26,
  // docs/pose-experiments.md "Re-measured on the honest gaps"): 250 failures at 10, 246 at 14 and at 18 (four
  // wheels fixed, none broken), median detection unchanged (the wide search runs in a quarter of
  // the cycles, and only those change).
  double escalate_max_cost_px = 14;
  int refine_iterations = 20;      // per candidate (outer ICP iterations); cut short at the deadline
  // The best this many candidates are refined by the render-based PoseRefiner with the cell's one
  // view. 0 by default: measured on mfc-sim bins, one-view refinement of the fitted pose made it
  // worse (median centre error 0.76 -> 1.01 mm, rotation 0.51 -> 0.81 deg, same detections;
  // docs/results.md Table 2: worse on every axis), while two views improve it.
  int refine_candidates = 0;
  // Threads of every stage of a cycle (edges, lines, distance transforms, search, fits); 0 = the
  // calling thread's OpenMP setting (OMP_NUM_THREADS, else every core).
  int threads = 0;
  DepthEdgeParams depth_edges;
  // Grasp features per part type (obj_id, feature; several per part: the best one counts), for
  // PoseCandidate::grasp_visibility (Sec. 4.4's "whether the grasp feature is visible"). A part
  // type without any keeps 1.
  std::vector<std::pair<int, GraspFeature>> grasp_features;
  // Diagnostics (mfc-eval): every fitted hypothesis is also reported in PipelineResult::trace.
  // Allocates per cycle; off in the daemon.
  bool trace = false;
};

struct PoseCandidate {
  int obj_id = 0;               // BOP object id of the part type (from its .tdb)
  std::string part;             // part name from the .tdb
  int view = -1;                // template view (out-of-plane rotation) that matched
  cv::Matx33d R_m2c = cv::Matx33d::eye();  // model -> camera rotation
  cv::Vec3d t_m2c_mm{0, 0, 0};  // model origin in the camera frame, mm
  double score = 0;             // 0..1, higher is better: the fitted rank (TemplatePoseFit score less the
                                // unexplained-edge penalty), clamped; without the fit (baselines)
                                // 1 / (1 + c / 2 px) of the search cost c with the penalty
  double cost_px = 0;           // mean directional chamfer cost at the final pose
  double coverage = 0;          // fraction of image edges inside the part's outline it explains
  double rank_px = 0;           // the search's ranking measure: cost_px + the unexplained-edge penalty
  double fit_rank = 0;          // the rank after TemplatePoseFit (fit score less unexplained edges)
  bool refined = false;         // false: coarse pose only (refinement skipped or failed)
  // 0..1: how clearly its best grasp feature is on top and facing the camera at the final pose
  // (vision/pose/grasp_visibility.hpp); 1 when its part type has no grasp feature configured.
  double grasp_visibility = 1;
  cv::Rect2d box;               // image bounding box of the matched template
};

struct StageTimes {
  double edges_ms = 0, lines_ms = 0, distance_ms = 0, search_ms = 0, pose_ms = 0, refine_ms = 0,
         total_ms = 0;
};

// One hypothesis of the cycle as the search found it and as the fit left it (PipelineConfig::trace).
struct HypothesisTrace {
  int obj_id = 0;
  int round = 1;              // the search round that found it (PipelineConfig::search_rounds); 0: the
                              // escalation's wide search (PipelineConfig::escalate_below)
  int search_view = -1, fitted_view = -1;
  double search_cost_px = 0;  // mean directional chamfer cost of the search hit
  double coverage = 0;        // explained-edge fraction at the search hit
  cv::Matx33d R_coarse = cv::Matx33d::eye(), R_fitted = cv::Matx33d::eye();  // model -> camera
  cv::Vec3d t_coarse_mm{0, 0, 0}, t_fitted_mm{0, 0, 0};
  double fit_rank = -1;       // as PoseCandidate::fit_rank; -1 = fit refused
  // The fit's measures at the fitted pose (TemplateFitResult), what fit_rank is made of.
  double fit_score = 0, fit_coverage = 0, inlier_fraction = 0, mean_cost_px = 0;
  double view_points = 0;     // the fitted view's edge points at the fitted distance
};

struct PipelineResult {
  std::vector<PoseCandidate> candidates;  // best first; capacity reserved once
  StageTimes times;
  bool degraded = false;      // the deadline cut a stage short: best-so-far result
  int edge_pixels = 0;
  int query_lines = 0;
  uint64_t hypotheses = 0;    // FDCM hypotheses evaluated by the search, all rounds
  int views_searched = 0;     // template views searched, all rounds (fewer than loaded when degraded)
  int rounds = 1;             // search rounds run (PipelineConfig::search_rounds; fewer near the deadline)
  bool escalated = false;     // the wide search ran (PipelineConfig::escalate_below)
  std::vector<HypothesisTrace> trace;  // PipelineConfig::trace only: every fitted hypothesis, search order,
                                       // before the turned-over check
};

// How the last processed image scores a given pose of a part, measured the way the search
// scores its own hypotheses (for the evaluation: was a miss the search's or the cost's?).
struct PoseScore {
  int view = -1;           // nearest template view (symmetry-aware)
  double view_angle_deg = 0;  // rotation between the given pose and that view's coarse pose
  double cost_px = 0;      // mean directional chamfer cost after the local fit (fit_distance)
  double coverage = 0;     // fraction of image edges inside the outline the view explains
  double rank_px = 0;      // cost_px + unexplained-edge penalty: compare with PoseCandidate::rank_px
  double fit_score = 0;    // TemplatePoseFit score from the view's coarse pose: compare with PoseCandidate::score
  double exact_score = 0;  // the same rank at the given pose itself, unfitted (do the edges prefer it?)
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

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Draws the candidates (model outline at the pose, index, score) over a grey image.
cv::Mat3b draw_candidates(const cv::Mat1b& image, const PipelineResult& result, const CameraConfig& camera);

}  // namespace mfcd::vision
