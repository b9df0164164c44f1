#pragma once
// Simulated bins for the synthetic experiments of paper Section 5.1.1: parts of mixed
// types dropped in stacked, physically plausible resting poses into a bin under the
// multi-flash camera, rendered with cast shadows, then corrupted the way the paper did
// (missing depth edges, clutter line segments). docs/datasets.md describes the method.

#include "vision/camera/camera.hpp"
#include "vision/camera/mfc_frames.hpp"
#include "vision/dataset/height_map.hpp"
#include "vision/dataset/resting_poses.hpp"
#include "vision/edges/depth_edges.hpp"
#include "vision/model/mesh.hpp"
#include "vision/render/mfc_renderer.hpp"

#include <opencv2/core.hpp>

#include <cstdint>
#include <memory>
#include <random>
#include <string>
#include <vector>

namespace mfcd::vision {

// One part type: its mesh (mm, the STL's own frame) and BOP object id.
struct PartModel {
  int obj_id = 0;
  std::string name;
  Mesh mesh;
  // Optional symmetry hints, written to models_info.json in BOP's form.
  struct ContinuousSymmetry {
    cv::Vec3d axis{0, 0, 1};
    cv::Vec3d offset{0, 0, 0};
  };
  std::vector<cv::Matx44d> symmetries_discrete;  // model-frame transforms (mm)
  std::vector<ContinuousSymmetry> symmetries_continuous;
};

// The bin: an open box whose inner floor lies at the camera's working distance, centred on
// the optical axis, walls parallel to the image axes.
struct BinGeometry {
  double inner_x_mm = 150;
  double inner_y_mm = 110;
  double wall_height_mm = 60;
  double wall_thickness_mm = 5;
  double floor_thickness_mm = 5;
};
// Bin mesh in its own frame: inner floor at z = 0, walls rising towards -z (the camera).
Mesh make_bin_mesh(const BinGeometry& bin);

// (a) Missing depth edges: the 8 flash images are made equal over short stretches of the
// true depth edges, so no shadow ratio remains there.
struct MissingEdgeOptions {
  bool enabled = true;
  double fraction = 0.12;  // wanted share of the depth-edge pixels found in the clean images
  double stretch_px = 14;  // length of one removed stretch along the edge
};

// (b) Clutter: thin square rods (wires, sticks) dropped into the bin as real geometry, not
// part of the ground truth; their outlines are depth edges like any other.
struct ClutterOptions {
  bool enabled = true;
  int min_rods = 6;
  int max_rods = 12;
  double min_length_mm = 15;
  double max_length_mm = 60;
  double width_mm = 4;
};

struct BinSceneOptions {
  BinGeometry bin;
  int parts_per_image = 6;
  // Placements that leave any part (new or earlier) more occluded than this are rejected
  // (1 = no limit). Occlusion = 1 - visible pixels / pixels of the part rendered alone.
  double max_occlusion = 1.0;
  double shiny_fraction = 0.3;    // share of parts with a shiny (specular) material
  double painted_fraction = 0.3;  // share of parts painted with stripes or a checker
  double cell_mm = 0.5;           // height-map grid
  double clearance_mm = 0.3;      // gap left between a dropped part and what it rests on
  double contact_tolerance_mm = 1.0;
  int attempts_per_object = 300;
  // How a drop picks the resting face: with probability proportional to its support area, or to
  // the solid angle it subtends at the centre of mass (the quasi-static landing model, which
  // puts flat parts on their rims less often; docs/datasets.md).
  enum class RestingWeight { support_area, solid_angle };
  RestingWeight resting_weight = RestingWeight::support_area;
  // Leaning parts: each drop of a part tilts its resting pose by an angle drawn uniformly in
  // [0, max_lean_deg] about a random horizontal axis, and the tilted part is kept only where it
  // rests stably (its centre of mass over the hull of its contacts), which on the bare floor it
  // mostly does not: it leans on the parts below. Parts in a real bin lean; 0 (the default)
  // keeps every part in a resting pose on a horizontal plane and the random draws as they were.
  double max_lean_deg = 0;
  MissingEdgeOptions missing;
  ClutterOptions clutter;
  // True depth edges: discontinuities above this jump (mm) of the rendered depth.
  float edge_min_jump_mm = 4.0f;
  double edge_tolerance_px = 1.5;
  RenderOptions render;
};

// One object in the bin: p_camera = R * p_model + t (mm).
struct PlacedObject {
  int model = -1;  // index into BinSimulator::models(), or -1 for a clutter rod
  int rod = -1;    // index of the rod mesh for clutter
  cv::Matx33d R = cv::Matx33d::eye();
  cv::Vec3d t_mm{0, 0, 0};
  Material material;
};

struct BinLayout {
  std::vector<PlacedObject> parts;    // in drop order: later parts may rest on earlier ones
  std::vector<PlacedObject> clutter;  // rods, dropped after the parts
  int rejected_placements = 0;
};

struct CorruptionReport {
  int true_edge_px = 0;         // depth discontinuities (> edge_min_jump_mm) of the depth image
  double recall_clean = 0;      // share of them DepthEdgeExtractor finds in the clean images
  double recall_corrupted = 0;  // ... in the stored (corrupted) images
  double removed_fraction = 0;  // 1 - recall_corrupted / recall_clean (measured)
  int stretches = 0;            // equalised stretches
  // Edge pixels of the stored images farther than edge_tolerance_px from every edge pixel the
  // extractor finds in the clean images, per clean edge pixel: edges the removal itself drew
  // (a stretch that lifts a wide cast shadow only partly moves the edge instead of removing it).
  double added_fraction = 0;
  int clutter_rods = 0;
};

// Ground truth of one part in one image (BOP's scene_gt + scene_gt_info).
struct PartInstance {
  int model = -1;
  int obj_id = 0;
  cv::Matx33d R;
  cv::Vec3d t_mm;
  cv::Mat1b mask_all;    // silhouette of the part rendered alone (image pixels)
  cv::Mat1b mask_visib;  // its visible pixels in the scene
  // As BOP's calc_gt_info: bbox_obj and px_count_all are of the whole silhouette, also where it
  // lies outside the image (the box may then extend beyond it), so a part cut by the image
  // border counts as partly hidden in visib_fract.
  cv::Rect bbox_obj, bbox_visib;
  int px_count_all = 0, px_count_valid = 0, px_count_visib = 0;
  double visib_fract = 0;
};

struct SimulatedImage {
  BinLayout layout;
  std::vector<PartInstance> instances;  // one per layout.parts, same order
  MfcFrames frames;                     // as stored: corrupted when corruptions are on
  cv::Mat1f depth_mm;
  CorruptionReport corruption;
};

class BinSimulator {
 public:
  // Uploads the models, the bin and the rods to an offscreen renderer. Throws
  // std::invalid_argument when a model has no stable resting pose or options are absurd.
  BinSimulator(const CameraConfig& camera, std::vector<PartModel> models, const BinSceneOptions& options = {});
  ~BinSimulator();

  // Drops parts_per_image parts (types drawn uniformly) and the clutter rods. Deterministic
  // in the seed. Fewer parts are placed when the bin is too full (every attempt rejected).
  BinLayout layout(uint64_t seed);
  // Layout, render, ground truth and corruptions.
  SimulatedImage simulate(uint64_t seed);
  // Render, ground truth and corruptions of a given layout (e.g. one of layout(), edited).
  SimulatedImage simulate(BinLayout layout, uint64_t seed);

  // The render list of a layout: table, bin, parts (in order), rods. The rendered
  // part_index of parts[k] is k + first_part_index().
  std::vector<ScenePart> scene_parts(const BinLayout& layout) const;
  static constexpr int first_part_index() { return 3; }

  const std::vector<PartModel>& models() const { return models_; }
  const std::vector<std::vector<RestingPose>>& resting_poses() const { return poses_; }
  const Mesh& rod_mesh(int rod) const { return rods_[static_cast<size_t>(rod)]; }
  const Mesh& bin_mesh() const { return bin_; }
  const BinSceneOptions& options() const { return options_; }
  const CameraConfig& camera() const { return camera_; }
  MfcRenderer& renderer() { return *renderer_; }

 private:
  // Drops one object at a random spot; false when every attempt was rejected.
  bool drop(BinLayout& layout, bool is_part, HeightMap& top, std::vector<int>& px_alone, std::mt19937_64& rng);
  // True when no part of the layout is more occluded than options_.max_occlusion.
  bool occlusion_ok(const BinLayout& layout, std::vector<int>& px_alone);
  // The pixel count and bounding box of a part's whole silhouette, given its silhouette in the
  // image (`in_image`, rendered alone): the same when that touches no image border, else
  // rendered again on a canvas three times the image's size each way, centred on it.
  int whole_silhouette(const ScenePart& part, const cv::Mat1b& in_image, cv::Rect* bbox);
  void corrupt(SimulatedImage& image, uint64_t seed);
  CameraConfig camera_;
  std::vector<PartModel> models_;
  BinSceneOptions options_;
  std::vector<std::vector<RestingPose>> poses_;
  std::vector<cv::Vec3d> com_;
  Mesh bin_;
  std::vector<Mesh> rods_;
  std::unique_ptr<MfcRenderer> renderer_;
  // whole_silhouette's renderer, made when first needed: the same meshes added in the same order,
  // so a ScenePart's mesh id means the same mesh in both.
  std::unique_ptr<MfcRenderer> wide_renderer_;
  std::unique_ptr<DepthEdgeExtractor> extractor_;
  int table_id_ = -1, bin_id_ = -1;
  std::vector<int> model_ids_, rod_ids_;
};

}  // namespace mfcd::vision
