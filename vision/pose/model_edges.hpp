#pragma once
// Model edge points at a pose (paper Sec. 4.5: "render the 3D CAD model with the current pose
// estimate"): the part alone is rendered (depth only) in a window around its projection,
// its depth discontinuities (occluding contour and self-occlusions) and optionally its
// creases are found, and each edge pixel, subsampled to a bounded count, is back-projected to
// a 3-D point in the model frame with its 2-D image direction.
//
// Edge pixels are on the near (occluding) side of a jump, like depth_discontinuities()
// (edge_evaluation.hpp), but a jump only counts when it is also large against the depth step
// on the near side: a face seen at a grazing angle changes depth by several mm per pixel
// without any occlusion, and the multi-flash camera (which sees cast shadows) finds no edge
// there.

#include "vision/camera/camera.hpp"
#include "vision/edges/edge_tangents.hpp"
#include "vision/model/mesh.hpp"
#include "vision/pose/rigid_transform.hpp"
#include "vision/render/mfc_renderer.hpp"

#include <opencv2/core.hpp>

#include <optional>
#include <vector>

namespace mfcd::vision {

// A part as the pose code sees it: its mesh in the renderer and its bounding box (to place
// the render window).
struct PoseModel {
  int mesh_id = -1;                                // from MfcRenderer::add_mesh
  cv::Vec3d bbox_min{0, 0, 0}, bbox_max{0, 0, 0};  // mm, model frame
};
inline PoseModel pose_model(int mesh_id, const Mesh& mesh) {
  const cv::Vec3f lo = mesh.bbox_min(), hi = mesh.bbox_max();
  return {mesh_id, cv::Vec3d(lo[0], lo[1], lo[2]), cv::Vec3d(hi[0], hi[1], hi[2])};
}

// The window (full-image pixels) that holds `model` at `m2c`: its projected bounding box plus
// `margin_px`, limited to the image plus the margin, its sizes rounded up to 32 px (so that nearby
// poses reuse the renderer's framebuffer); none when the part is outside the image. Throws
// std::invalid_argument, naming `what`, when the part reaches behind the camera.
std::optional<cv::Rect> pose_window(const PinholeCamera& camera, const PoseModel& model, const RigidTransform& m2c,
                                    int margin_px, const char* what);

struct ModelEdgePoint {
  cv::Vec3d point_model;  // mm, model frame
  cv::Point2d pixel;      // where it was seen, full-image pixel coordinates of the view
  float angle = 0;        // image tangent angle at the render pose, [0, pi)
};

struct ModelEdgeParams {
  int max_points = 400;            // per view; evenly subsampled along the edge pixel list
  float min_depth_jump_mm = 2.0f;  // a neighbour farther by more than this makes a depth edge ...
  float min_jump_ratio = 1.0f;     // ... than the near surface continued (its step times this)
  bool creases = false;            // also use creases (visible folds of the surface)
  float crease_angle_deg = 30.0f;
  float crease_max_step_mm = 3.0f;
  int margin_px = 6;  // window margin around the projected bounding box
  int border_px = 2;  // points closer than this to the image border are dropped
};

// Occluding edges of a depth image (0 = no surface): a surface pixel whose 4-neighbour shows no
// surface, or lies farther than the near surface continued by one pixel (its depth step from
// the pixel on the opposite side, times min_jump_ratio) by more than min_jump_mm. `edges`
// gets 255 there, 0 elsewhere. With min_jump_ratio = 0 this is depth_discontinuities().
// With `part_index` (MfcRenderer's), a farther neighbour of another object (or background) is
// always an occluding edge, whatever the near surface's slope: the flashes cast a shadow there.
void occluding_edges(const cv::Mat1f& depth_mm, float min_jump_mm, float min_jump_ratio, cv::Mat1b& edges,
                     const cv::Mat1b* part_index = nullptr);

class ModelEdgeSampler {
 public:
  // Borrows the renderer (its EGL context belongs to the calling thread). sample() changes the
  // renderer's camera; callers that also render full frames set theirs again.
  ModelEdgeSampler(MfcRenderer& renderer, const ModelEdgeParams& params = {});
  void set_params(const ModelEdgeParams& p) { params_ = p; }

  // Renders the model at model_to_camera in `camera` and fills `out` (cleared first) with
  // at most params.max_points edge points inside the image. Throws std::invalid_argument when
  // the part is behind the camera. An empty result means no edge of the part is visible.
  void sample(const PoseModel& model, const RigidTransform& model_to_camera, const PinholeCamera& camera,
              std::vector<ModelEdgePoint>& out);

  const ModelEdgeParams& params() const { return params_; }
  // The last render window (full-image coordinates) and its depth, for inspection and tests.
  const cv::Rect& window() const { return window_; }
  const cv::Mat1f& depth() const { return depth_; }

 private:
  MfcRenderer& renderer_;
  ModelEdgeParams params_;
  cv::Rect window_;
  cv::Mat1f depth_;
  cv::Mat1b part_index_, mask_;
  std::vector<cv::Point> pixels_;
  std::vector<ScenePart> scene_;
};

}  // namespace mfcd::vision
