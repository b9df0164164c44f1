#include "vision/pose/model_edges.hpp"

#include "vision/edges/edge_evaluation.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace mfcd::vision {

ModelEdgeSampler::ModelEdgeSampler(MfcRenderer& renderer, const ModelEdgeParams& params)
    : renderer_(renderer), params_(params) {
  if (params.max_points < 1) throw std::invalid_argument("model edges: max_points must be >= 1");
  if (!(params.min_depth_jump_mm > 0)) throw std::invalid_argument("model edges: min_depth_jump_mm must be > 0");
  if (params.margin_px < 2) throw std::invalid_argument("model edges: margin_px must be >= 2");
  scene_.resize(1);
  pixels_.reserve(4096);
}

void occluding_edges(const cv::Mat1f& depth, float min_jump, float min_ratio, cv::Mat1b& edges,
                     const cv::Mat1b* part_index) {
  if (part_index && part_index->size() != depth.size())
    throw std::invalid_argument("occluding_edges: part index and depth images differ in size");
  const int W = depth.cols, H = depth.rows;
  edges.create(depth.size());
  edges.setTo(0);
  // Is the neighbour at (x + dx, y + dy) behind an occluding edge seen from (x, y)?
  const auto occludes = [&](int x, int y, int dx, int dy, float z) {
    const int u = x + dx, v = y + dy;
    if (u < 0 || v < 0 || u >= W || v >= H) return false;
    const float q = depth(v, u);
    if (q <= 0) return true;
    const float jump = q - z;
    if (jump <= min_jump) return false;
    if (part_index && (*part_index)(v, u) != (*part_index)(y, x)) return true;  // another object behind
    // The near surface's own slope, continued one pixel: a grazing face rises by several mm
    // per pixel without occluding anything.
    const int bu = x - dx, bv = y - dy;
    float step = 0;
    if (bu >= 0 && bv >= 0 && bu < W && bv < H && depth(bv, bu) > 0) step = std::max(0.f, z - depth(bv, bu));
    return jump - min_ratio * step > min_jump;
  };
  for (int y = 0; y < H; ++y) {
    const float* d = depth.ptr<float>(y);
    uint8_t* e = edges.ptr<uint8_t>(y);
    for (int x = 0; x < W; ++x) {
      const float z = d[x];
      if (z <= 0) continue;
      if (occludes(x, y, 1, 0, z) || occludes(x, y, -1, 0, z) || occludes(x, y, 0, 1, z) || occludes(x, y, 0, -1, z))
        e[x] = 255;
    }
  }
}

std::optional<cv::Rect> pose_window(const PinholeCamera& camera, const PoseModel& model, const RigidTransform& m2c,
                                    int margin_px, const char* what) {
  // The projected bounding box plus a margin, limited to the image plus the margin.
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (int c = 0; c < 8; ++c) {
    const cv::Vec3d corner((c & 1) ? model.bbox_max[0] : model.bbox_min[0],
                           (c & 2) ? model.bbox_max[1] : model.bbox_min[1],
                           (c & 4) ? model.bbox_max[2] : model.bbox_min[2]);
    const cv::Vec3d p = m2c.apply(corner);
    if (!(p[2] > 1.0))
      throw std::invalid_argument(std::string(what) + ": part (mesh " + std::to_string(model.mesh_id) +
                                  ") reaches behind the camera (bounding-box corner at z = " + std::to_string(p[2]) +
                                  " mm)");
    const cv::Point2d q = camera.project(p);
    x0 = std::min(x0, q.x);
    y0 = std::min(y0, q.y);
    x1 = std::max(x1, q.x);
    y1 = std::max(y1, q.y);
  }
  const int m = margin_px;
  const int W = camera.image_size.width, H = camera.image_size.height;
  const int wx0 = std::max(static_cast<int>(std::floor(x0)) - m, -m);
  const int wy0 = std::max(static_cast<int>(std::floor(y0)) - m, -m);
  const int wx1 = std::min(static_cast<int>(std::ceil(x1)) + m, W + m);
  const int wy1 = std::min(static_cast<int>(std::ceil(y1)) + m, H + m);
  if (wx1 - wx0 < 3 || wy1 - wy0 < 3) return std::nullopt;  // entirely outside the image
  // Sizes rounded up to 32 px so that nearby poses reuse the renderer's framebuffer.
  return cv::Rect(wx0, wy0, (wx1 - wx0 + 31) / 32 * 32, (wy1 - wy0 + 31) / 32 * 32);
}

void ModelEdgeSampler::sample(const PoseModel& model, const RigidTransform& m2c, const PinholeCamera& camera,
                              std::vector<ModelEdgePoint>& out) {
  out.clear();
  const std::optional<cv::Rect> window = pose_window(camera, model, m2c, params_.margin_px, "model edges");
  if (!window) return;
  window_ = *window;
  const int W = camera.image_size.width, H = camera.image_size.height;
  const int ww = window_.width, wh = window_.height;
  const PinholeCamera crop = camera.cropped(window_);
  renderer_.set_camera(crop);
  scene_[0].mesh_id = model.mesh_id;
  scene_[0].R = m2c.R;
  scene_[0].t_mm = m2c.t;
  renderer_.render_depth(scene_, depth_, part_index_);

  occluding_edges(depth_, params_.min_depth_jump_mm, params_.min_jump_ratio, mask_, &part_index_);
  if (params_.creases) mask_ |= depth_creases(depth_, crop.K, params_.crease_angle_deg, params_.crease_max_step_mm);

  // Edge pixels inside the image (away from its border).
  pixels_.clear();
  const int b = params_.border_px;
  for (int y = 0; y < wh; ++y) {
    const int fy = y + window_.y;
    if (fy < b || fy >= H - b) continue;
    const uint8_t* mk = mask_.ptr<uint8_t>(y);
    for (int x = 0; x < ww; ++x) {
      const int fx = x + window_.x;
      if (mk[x] && fx >= b && fx < W - b) pixels_.emplace_back(x, y);
    }
  }
  const size_t n = pixels_.size();
  const size_t keep = std::min(n, static_cast<size_t>(params_.max_points));
  if (out.capacity() < keep) out.reserve(static_cast<size_t>(params_.max_points));
  const cv::Matx33d Rt = m2c.R.t();
  for (size_t k = 0; k < keep; ++k) {
    // Evenly spaced through the list: equal numbers of edge pixels between samples.
    const cv::Point px = pixels_[k * n / keep];
    const double z = depth_(px.y, px.x);
    const cv::Vec3d p_cam((px.x - crop.cx()) * z / crop.fx(), (px.y - crop.cy()) * z / crop.fy(), z);
    out.push_back(
        {Rt * (p_cam - m2c.t), cv::Point2d(px.x + window_.x, px.y + window_.y), edge_tangent_at(mask_, px.x, px.y)});
  }
}

}  // namespace mfcd::vision
