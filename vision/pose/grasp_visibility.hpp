// Is a candidate's grasp feature on top? Sec. 4.4's pick candidates are ranked also by "whether
// the grasp feature is visible": a part whose grasp spot lies under another part cannot be taken
// there even when the part itself is found (the paper's second cause of failed grasps, Sec.
// 5.1.3). mfcd has no depth map, only depth edges with their shadow sides (which side of an
// edge is nearer), so the answer is read from those: rays from points of the spot walk outwards
// to where the surface under the spot ends. If that border is the part's own edge (near one of
// its projected template points, turned the same way, the part on the near side), the spot is
// on the part; if the surface there steps down onto something else, the spot lies on a surface
// above the part's: covered. Things lying on that surface are walked across (their near sides
// face the ray on the way in and away on the way out), so a rod on a cover does not uncover the
// spot and a rod on the part does not cover it. Measured against the rendered truth in
// docs/pose.md "Grasp features".
#pragma once

#include <opencv2/core.hpp>

#include <cmath>
#include <string>

#include "vision/camera/camera.hpp"
#include "vision/edges/depth_edges.hpp"
#include "vision/pose/coarse_pose.hpp"
#include "vision/templates/template_database.hpp"

namespace mfcd::vision {

// The spot on a part the gripper takes it by (a hole for pins, a face for a suction cup), model
// frame: the paper's breaker is taken by pins through its hole, and a hole under another part
// was one of its two causes of failed grasps (Sec. 5.1.3).
struct GraspFeature {
  cv::Vec3d point_mm{0, 0, 0};  // centre of the spot on the part's surface
  double radius_mm = 4;         // the spot is a disc of this radius around it, seen in the image
  // Direction the gripper comes from (out of the spot's surface), model frame; zero = any. The
  // spot counts as not visible when it faces away from the camera by more than max_tilt_deg.
  cv::Vec3d approach{0, 0, 0};
  double max_tilt_deg = 60;

  // Empty when usable; else the reason (radius 0 < r <= 100 mm, tilt 0..180 degrees, finite).
  std::string validate() const;
};

struct GraspVisibilityParams {
  int rays = 16;            // directions cast from every sample point
  double max_ray_px = 160;  // how far a ray looks for an edge (about a part's projected size)
  int ring_points = 6;      // sample points on the rim of the grasp disc, besides its centre
  // A foreign edge met at a grazing angle (|cos| between the ray and the edge normal below
  // this) says nothing about which side the spot is on: the ray goes on past it.
  double min_cos = 0.25;
  double own_tolerance_rad = 0.5;  // ~29 degrees between the edge's and the point's oriented tangents
};

// An oriented tangent (radians, any turn) as an `own` pixel value, 1..254 (0 = no own point):
// 254 steps of 1.4 degrees, well within own_tolerance_rad.
inline unsigned char encode_own_direction(double angle) {
  constexpr double kTwoPi = 6.283185307179586;
  double a = std::fmod(angle, kTwoPi);
  if (a < 0) a += kTwoPi;
  return static_cast<unsigned char>(1 + static_cast<int>(a / kTwoPi * 254.0 + 0.5) % 254);
}
inline double decode_own_direction(unsigned char v) { return (v - 1) * 6.283185307179586 / 254.0; }

struct GraspVisibility {
  double visible = 1;        // 0..1: mean over the sample points of own / (own + covered) of their
                             // rays; a sample point no ray told anything about counts 1
  int own_votes = 0;         // rays whose surface ended at the part's own edge
  int covered_votes = 0;     // rays whose surface stepped down onto something not the part's outline
  int samples_outside = 0;   // sample points outside the image (count as covered)
  bool faces_camera = true;  // the approach direction is within the feature's max_tilt_deg
};

// `own`: at the pixels near the candidate's projected template points (within the fit's
// tolerance), the point's oriented tangent at the pose (encode_own_direction), 0 elsewhere;
// an image edge there is the candidate's own when its oriented tangent (edge direction and
// shadow side) agrees within `own_tolerance_rad`. Same size as `edges.edges`. `grasp_px`, `radius_px`:
// the grasp feature's disc in the image. Needs `edges.shadow` (depth edges); with an empty
// `shadow` (Canny) nothing can be told and the result is 1. No allocation.
GraspVisibility grasp_visibility(const DepthEdges& edges, const cv::Mat1b& own, const cv::Point2d& grasp_px,
                                 double radius_px, const GraspVisibilityParams& params = {});

// Whether the feature's approach direction at `pose` (model -> camera) is within its
// max_tilt_deg of the line of sight back to the camera (always, without an approach direction).
bool grasp_faces_camera(const GraspFeature& feature, const RigidPose& pose);

// The whole test for part `db` at `pose`: facing the camera, then grasp_visibility with the
// part's own edges taken from its nearest template view at the pose (within `own_tolerance_px`
// of its projected points). `own` is a workspace: resized to the image on first use, left zero.
GraspVisibility grasp_feature_visibility(const DepthEdges& edges, const TemplateDatabase& db,
                                         const PinholeCamera& camera, const RigidPose& pose,
                                         const GraspFeature& feature, double own_tolerance_px, cv::Mat1b& own,
                                         const GraspVisibilityParams& params = {});

}  // namespace mfcd::vision
