#pragma once
// The template database of one part (paper Sec. 4.3): K views of the part's CAD model from
// out-of-plane rotations sampled uniformly on the sphere, each rendered with the simulated
// multi-flash camera at the working distance, reduced to depth edges and then to lines.
// Each view keeps what the pose stages need: the pose it was rendered at and, for every edge
// pixel, the 3-D model point it came from.
//
// File format (*.tdb, docs/template-database.md): a fixed little-endian header (magic,
// version, payload size, CRC-32 of the payload) and a payload holding the camera/flash geometry
// it was built for, the part (name, BOP obj_id, symmetry, mesh), the views, the edge offset
// profiles, the views' symmetry and the part's turns.

#include "vision/camera/camera.hpp"
#include "vision/common/segment.hpp"
#include "vision/model/mesh.hpp"
#include "vision/model/mesh_turns.hpp"
#include "vision/templates/edge_offset_profile.hpp"

#include <opencv2/core.hpp>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace mfcd::vision {

// Symmetry hint of a part about its own z axis, so symmetric parts do not waste templates.
struct PartSymmetry {
  enum class Kind : uint8_t { none = 0, discrete_z = 1, continuous_z = 2 };
  Kind kind = Kind::none;
  int order = 1;  // discrete_z: the part maps onto itself when turned by 360/order degrees about z

  // "none", "z:N" (N-fold about z) or "z:inf" (any rotation about z). Throws std::invalid_argument.
  static PartSymmetry parse(const std::string& text);
  std::string str() const;
  // The rotations (model frame) that map the part onto itself; continuous: none listed.
  std::vector<cv::Matx33d> discrete_rotations() const;
  // Whether every turn of `other` is one of this symmetry's (a coarser fold of the same part).
  bool includes(const PartSymmetry& other) const;
};

// One edge pixel of a template view and the model point it images.
struct TemplateEdgePoint {
  cv::Point2f pixel;  // relative to the view's origin (image of the part centre)
  // Edge tangent of the pixel chain (edge_tangents), radians, image axes, oriented: in [0, 2 pi),
  // turned so that its left normal (-sin, cos) points into the shadow, away from the part
  // (oriented_tangent). Modulo pi it is the undirected tangent.
  float direction = 0;
  cv::Vec3f model_mm;  // the visible surface point on the near side of the depth edge, model frame
};

struct TemplateView {
  int index = 0;
  cv::Vec3d view_direction;                // unit vector from the part centre towards the camera, model frame
  cv::Matx33d R_m2c = cv::Matx33d::eye();  // pose the view was rendered at: p_cam = R_m2c p_model + t_m2c
  cv::Vec3d t_m2c_mm{0, 0, 0};
  LineSet lines;  // origin = image of the part centre (the principal point)
  std::vector<TemplateEdgePoint> points;
  cv::Rect2f box;  // bounding box of the edge pixels, relative to the origin
};

struct TemplateDatabase {
  // Version 6 stores the part's turns; older files are refused (re-run mfc-teach): the pose
  // checks need the turns, and finding them costs 0.2-0.9 s a part, paid once when teaching.
  static constexpr uint32_t kVersion = 6;
  static constexpr uint32_t kOldestVersion = 6;

  std::string part_name;
  int obj_id = 0;  // BOP object id
  // What counts as the same pose of the part: the turns a gripper and the evaluation do not tell
  // apart, and the pose checks' turns (phase turns for an N-fold part, N >= 3).
  PartSymmetry symmetry;
  // The symmetry the views were folded by (view_sampling) and that finds a pose's nearest view:
  // `symmetry` or a finer one its edges still show, as the knob's 2-fold pointer groove on its
  // 10-fold flutes (docs/template-database.md). Always included in `symmetry`.
  PartSymmetry views_symmetry;
  CameraConfig camera;           // the camera and flash geometry the views were rendered with
  double distance_mm = 0;        // distance of the part centre from the lens along the optical axis
  cv::Vec3d center_mm{0, 0, 0};  // model-frame point placed on the optical axis (bounding-box centre)
  double diameter_mm = 0;        // largest distance between two model vertices (BOP models_info)
  int sphere_samples = 0;        // K: views over the whole sphere before the symmetry reduction
  int q = 120;                   // orientation channels the lines were fitted with
  bool oriented = true;          // lines carry edge polarity: q channels over 2 pi (LineSet::oriented)
  Mesh mesh;                     // the part model (mm), for refinement and overlays
  std::vector<TemplateView> views;
  // Where the extractor puts edge pixels relative to the true outline, by the outline's direction
  // (EdgeOffsetProfile): under the views' own rendering conditions (noise off, background plane)
  // and under the query's (sensor noise, parts over a floor). Empty (version 3 files): the pose fit
  // makes no correction.
  EdgeOffsetProfile template_edge_offset, query_edge_offset;
  // The part's turns found from its mesh at teach time (find_part_turns): its symmetries and the
  // turns a pose is checked against (near-symmetries, turns over, phase turns), model frame.
  MeshTurns turns;
};

// Why a template file is refused.
class TemplateFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

void save_template_database(const TemplateDatabase& db, const std::filesystem::path& file);
// Throws TemplateFileError naming the file and the reason: not a template database (magic),
// another version, truncated, checksum mismatch, malformed content.
TemplateDatabase load_template_database(const std::filesystem::path& file);
// Throws TemplateFileError when `db` was built for another camera (intrinsics, image size,
// flash positions), naming what differs; `source` names the file in the message.
void check_template_camera(const TemplateDatabase& db, const CameraConfig& camera, const std::string& source);

}  // namespace mfcd::vision
