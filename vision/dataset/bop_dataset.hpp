#pragma once
// BOP-format scene datasets (https://bop.felk.cvut.cz) extended with multi-flash images:
// the writer stores simulated bins, the reader opens any dataset in this layout (mfc-detect
// evaluates on it). docs/datasets.md documents the layout, axes, units and keys.
//
//   <root>/camera.json                       BOP camera of the dataset (fx, fy, cx, cy, size, depth_scale)
//   <root>/models/obj_NNNNNN.ply             ASCII PLY with vertex normals, mm, the model (STL) frame
//   <root>/models/models_info.json
//   <root>/models_eval/                      the same files: the models BOP's evaluation reads
//   <root>/test_targets_bop19.json           BOP19 test targets of the split (written on request)
//   <root>/<split>/SSSSSS/scene_camera.json  cam_K, depth_scale, width, height, flash_positions_mm
//   <root>/<split>/SSSSSS/scene_gt.json      obj_id, cam_R_m2c, cam_t_m2c per instance
//   <root>/<split>/SSSSSS/scene_gt_info.json bbox_obj, bbox_visib, px_count_*, visib_fract
//   <root>/<split>/SSSSSS/scene_mfc_corruption.json  (written by the simulator; optional)
//   <root>/<split>/SSSSSS/flash/IIIIII_K.png, ambient/IIIIII.png, gray/IIIIII.png (a copy of
//                        ambient/ under BOP's name), depth/IIIIII.png,
//                        mask/IIIIII_GGGGGG.png, mask_visib/IIIIII_GGGGGG.png

#include "vision/camera/camera.hpp"
#include "vision/camera/mfc_frames.hpp"
#include "vision/dataset/bin_scene.hpp"

#include <opencv2/core.hpp>

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace mfcd::vision {

// Depth PNGs store depth_mm / kBopDepthScale as uint16 (0.1 mm steps, up to 6.5 m).
inline constexpr double kBopDepthScale = 0.1;
// A ground-truth instance is a BOP19 test target when at least this share of its silhouette is
// visible (visib_fract >= 0.1), as the toolkit's scripts/enumerate_test_targets.py counts them.
inline constexpr double kBopTargetMinVisibFract = 0.1;

struct BopModelInfo {
  double diameter = 0;  // largest distance between two vertices, mm
  cv::Vec3d min{0, 0, 0}, size{0, 0, 0};
  std::vector<cv::Matx44d> symmetries_discrete;
  std::vector<PartModel::ContinuousSymmetry> symmetries_continuous;
};
BopModelInfo compute_model_info(const PartModel& model);

struct BopSceneCamera {
  cv::Matx33d K = cv::Matx33d::eye();
  cv::Size image_size;
  double depth_scale = kBopDepthScale;
  std::vector<cv::Vec3d> flash_positions_mm;  // camera frame, firing order
  double working_distance_mm = 0;             // 0 when the dataset does not give it
  // BOP's cam_R_w2c / cam_t_w2c: world -> this image's camera (p_cam = R p_world + t, mm), when the
  // scene gives them (several views of one scene: the motion between two views follows).
  bool has_world_pose = false;
  cv::Matx33d R_w2c = cv::Matx33d::eye();
  cv::Vec3d t_w2c_mm{0, 0, 0};
  // A camera configuration for the depth-edge extractor and detector (no distortion).
  CameraConfig config() const;
};

struct BopGtPose {
  int obj_id = 0;
  cv::Matx33d R = cv::Matx33d::eye();  // cam_R_m2c
  cv::Vec3d t_mm{0, 0, 0};             // cam_t_m2c
};

struct BopGtInfo {
  cv::Rect bbox_obj, bbox_visib;  // x, y, w, h; (-1, -1, -1, -1) when empty
  int px_count_all = 0, px_count_valid = 0, px_count_visib = 0;
  double visib_fract = 0;
};

// One entry of a BOP19 test-target list: in image im_id of scene scene_id, inst_count instances
// of object obj_id are to be found.
struct BopTestTarget {
  int scene_id = 0, im_id = 0, obj_id = 0, inst_count = 0;
  bool operator==(const BopTestTarget&) const = default;
};

// The file name of a split's BOP19 test targets: the split's name without its split type
// (BOP's split[_SPLITTYPE] folders: "test" and "test_primesense" both give
// "test_targets_bop19.json").
std::string bop_test_targets_filename(const std::string& split);

// Writes a dataset. Models first (their ids are what scene_gt refers to), then scenes, then
// the test targets of every scene of the split.
class BopWriter {
 public:
  // `split` must be a plain folder name (not empty, no '/', not "." or ".."); else
  // std::invalid_argument.
  explicit BopWriter(std::filesystem::path root, std::string split = "test");
  // models/obj_NNNNNN.ply (with vertex normals) and models/models_info.json, and the same files
  // in models_eval/ (BOP evaluates with the models there). Object ids must be distinct and at
  // least 0 (BOP's ids), else std::invalid_argument naming the id.
  void write_models(const std::vector<PartModel>& models);
  void write_camera(const CameraConfig& camera);
  // <split>/SSSSSS/ with every image of the scene (image ids 0, 1, ...).
  void write_scene(int scene_id, const CameraConfig& camera, const std::vector<SimulatedImage>& images);
  // <split>/SSSSSS/ with one captured frame set as image 0: scene_camera.json, scene_gt.json
  // (`truth`, empty when unknown), flash/, ambient/ and gray/; no depth, masks or gt_info (a
  // capture has no rendering to take them from). Enough for BopDataset::frames and mfc-detect.
  void write_capture(int scene_id, const CameraConfig& camera, const MfcFrames& frames,
                     const std::vector<BopGtPose>& truth);
  // <root>/<bop_test_targets_filename(split)> from the scene_gt.json and scene_gt_info.json of
  // every scene folder of the split on disk (also scenes an earlier run left there), as
  // bop_test_targets computes them; call after the last write_scene. Returns the targets.
  std::vector<BopTestTarget> write_test_targets() const;
  const std::filesystem::path& root() const { return root_; }
  std::filesystem::path scene_dir(int scene_id) const;

 private:
  std::filesystem::path root_;
  std::string split_;
};

// The BOP19 test targets of the scenes in <root>/<split>/ (folders named by 6 digits), as the
// toolkit's scripts/enumerate_test_targets.py makes them: scenes and images in ascending order
// (images: the keys of scene_gt.json), within an image one entry per object id in the order of
// its first instance in scene_gt.json, inst_count = its instances with visib_fract >=
// kBopTargetMinVisibFract; an object id with no such instance gets no entry. Throws
// std::runtime_error naming the file on a missing or malformed scene_gt.json or
// scene_gt_info.json, or when the two list different instances for an image.
std::vector<BopTestTarget> bop_test_targets(const std::filesystem::path& root, const std::string& split);

// Per-vertex normals for the PLY: at each vertex (by index) the sum of the cross products of its
// triangles' edges, i.e. the face normals weighted by face area, normalised to unit length;
// (0, 0, 0) at a vertex no triangle of non-zero area uses. Outward for a closed mesh with
// counter-clockwise triangles. Vertices are taken as the mesh has them (load_mesh welds identical
// ones), so at a sharp edge the normal is the blend of the faces meeting there, as in BOP's own
// models; a triangle with vertices of its own keeps its face's normal.
std::vector<cv::Vec3f> vertex_normals(const Mesh& mesh);

// ASCII PLY as BOP's models are: per vertex float x y z nx ny nz (mm; normals from
// vertex_normals), per triangle a `vertex_indices` list.
void write_ply(const Mesh& mesh, const std::filesystem::path& file);

// What a standard BOP dataset does not say about the multi-flash camera, from elsewhere (a
// camera file the user gives): used only where scene_camera.json lacks the key.
struct BopCameraDefaults {
  std::vector<cv::Vec3d> flash_positions_mm;  // camera frame, firing order; empty = none given
  std::string source;                         // where they come from, for messages
};

// Reads a dataset. Every accessor checks what it reads and throws std::runtime_error
// naming the file (and key) and the reason on missing files, bad JSON, missing or
// ill-typed keys, image sizes that disagree with the camera's, or a flash image count
// that disagrees with the flash positions.
//
// Per image, the camera comes from scene_camera.json (cam_K, depth_scale, and the MFC
// extensions width, height, flash_positions_mm, working_distance_mm); an image size or depth scale
// an entry lacks comes from <root>/camera.json (BOP keeps them there), the flash positions from
// `defaults`. Refused only when none of them gives a needed value.
class BopDataset {
 public:
  // Opens <root>: needs models/models_info.json and <root>/<split>/; reads <root>/camera.json
  // when it exists (a malformed one is refused).
  explicit BopDataset(std::filesystem::path root, std::string split = "test", BopCameraDefaults defaults = {});

  const std::filesystem::path& root() const { return root_; }
  std::filesystem::path scene_dir(int scene_id) const;
  std::vector<int> scenes() const;              // sorted scene ids (folders named by 6 digits)
  std::vector<int> images(int scene_id) const;  // sorted image ids of scene_camera.json

  const std::map<int, BopModelInfo>& models_info() const { return models_info_; }
  std::filesystem::path model_path(int obj_id) const;

  BopSceneCamera camera(int scene_id, int image_id) const;
  std::vector<BopGtPose> ground_truth(int scene_id, int image_id) const;
  std::vector<BopGtInfo> ground_truth_info(int scene_id, int image_id) const;
  // The 8 (or however many LEDs scene_camera.json lists) flash images and the ambient.
  MfcFrames frames(int scene_id, int image_id) const;
  cv::Mat1f depth_mm(int scene_id, int image_id) const;
  cv::Mat1b mask_visib(int scene_id, int image_id, int instance) const;
  // The instance's whole silhouette (mask/), also where other objects hide it.
  cv::Mat1b mask(int scene_id, int image_id, int instance) const;

 private:
  void read_dataset_camera();
  cv::Mat1b mask_png(const char* folder, int scene_id, int image_id, int instance) const;
  std::filesystem::path root_, split_dir_;
  std::map<int, BopModelInfo> models_info_;
  // <root>/camera.json's image size and depth scale, those it gives (BOP's camera.json also has
  // fx, fy, cx, cy; the reader takes K from each image's cam_K, which BOP always gives).
  struct DatasetCamera {
    bool present = false;
    std::optional<cv::Size> image_size;
    std::optional<double> depth_scale;
  } dataset_camera_;
  BopCameraDefaults defaults_;
};

}  // namespace mfcd::vision
