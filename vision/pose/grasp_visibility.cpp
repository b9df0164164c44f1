#include "vision/pose/grasp_visibility.hpp"

#include "vision/pose/template_pose_fit.hpp"

#include <cmath>
#include <numbers>

namespace mfcd::vision {
namespace {

enum class Vote { none, own, covered };

// An image edge the candidate explains: near one of its points and turned like it, with the
// same side near (oriented tangents).
bool is_own(const DepthEdges& edges, const cv::Mat1b& own, int x, int y, const GraspVisibilityParams& params) {
  const double a = oriented_tangent(edges.direction(y, x), edges.shadow(y, x));
  double d = std::fmod(std::abs(a - decode_own_direction(own(y, x))), 2 * std::numbers::pi);
  if (d > std::numbers::pi) d = 2 * std::numbers::pi - d;
  return d <= params.own_tolerance_rad;
}

// Walks the pixels a ray from `p` crosses (every pixel, 4-connected, so that it cannot slip
// between the pixels of an 8-connected edge chain), the start pixel left out, and votes where the
// surface the start lies on ends: at the part's own edge (the part is that surface), or where it
// steps down to something farther that is not the part's outline (the surface lies on top of
// the part there: an occluder). Whatever lies on that surface (a step up) is walked across: each
// step up is matched by a step down on its far side before the walk is back on the surface. An
// edge met at a grazing angle says nothing and is walked past.
Vote cast_ray(const DepthEdges& edges, const cv::Mat1b& own, const cv::Point2d& p, double dx, double dy,
              const GraspVisibilityParams& params) {
  const cv::Mat1b& e = edges.edges;
  int x = static_cast<int>(std::floor(p.x + 0.5)), y = static_cast<int>(std::floor(p.y + 0.5));
  const int step_x = dx > 0 ? 1 : -1, step_y = dy > 0 ? 1 : -1;
  constexpr double kInf = 1e30;
  // Ray parameter (length along the ray) to the next vertical / horizontal pixel border, and
  // the length between two such borders. Pixel (x, y) spans [x - 0.5, x + 0.5).
  const double t_delta_x = dx != 0 ? std::abs(1.0 / dx) : kInf;
  const double t_delta_y = dy != 0 ? std::abs(1.0 / dy) : kInf;
  double t_max_x = dx != 0 ? ((x + 0.5 * step_x) - p.x) / dx : kInf;
  double t_max_y = dy != 0 ? ((y + 0.5 * step_y) - p.y) / dy : kInf;
  int level = 0, skip = 0;
  for (;;) {
    double t;
    if (t_max_x < t_max_y) {
      t = t_max_x, x += step_x, t_max_x += t_delta_x;
    } else {
      t = t_max_y, y += step_y, t_max_y += t_delta_y;
    }
    if (t > params.max_ray_px || x < 0 || y < 0 || x >= e.cols || y >= e.rows) return Vote::none;
    if (skip > 0 && e(y, x)) {
      --skip;
      continue;
    }
    skip = 0;
    if (!e(y, x)) continue;
    // The shadow normal points away from the occluding surface: along the ray, the ray steps
    // down onto a farther surface; against it, up onto a nearer one.
    const float s = edges.shadow(y, x);
    const double c = std::cos(s) * dx + std::sin(s) * dy;
    const bool down = c >= params.min_cos, up = c <= -params.min_cos;
    if (level == 0) {
      // Still on the spot's own surface: its border here tells what that surface is.
      if (own(y, x) && is_own(edges, own, x, y, params)) return Vote::own;
      if (down) return Vote::covered;  // it ends on top of something that is not the part's outline
      if (up) ++level;                 // something lies on it: walk across that to its far side
    } else {
      if (down) --level;
      if (up) ++level;
    }
    // Crossing a pixel-wide edge takes a step or two of the walk: skip the rest of this edge.
    skip = 2;
  }
}

}  // namespace

GraspVisibility grasp_visibility(const DepthEdges& edges, const cv::Mat1b& own, const cv::Point2d& grasp_px,
                                 double radius_px, const GraspVisibilityParams& params) {
  GraspVisibility out;
  if (edges.shadow.empty() || edges.edges.empty()) return out;
  CV_Assert(own.size() == edges.edges.size() && edges.shadow.size() == edges.edges.size());
  const int samples = 1 + (radius_px > 0.5 ? params.ring_points : 0);
  double sum = 0;
  for (int k = 0; k < samples; ++k) {
    cv::Point2d p = grasp_px;
    if (k > 0) {
      const double a = 2 * std::numbers::pi * (k - 1) / params.ring_points;
      p += cv::Point2d(radius_px * std::cos(a), radius_px * std::sin(a));
    }
    if (p.x < -0.5 || p.y < -0.5 || p.x >= edges.edges.cols - 0.5 || p.y >= edges.edges.rows - 0.5) {
      ++out.samples_outside;
      continue;  // a spot outside the image cannot be checked: it counts as covered
    }
    int covered = 0, own_edge = 0;
    for (int r = 0; r < params.rays; ++r) {
      const double a = 2 * std::numbers::pi * (r + 0.5) / params.rays;
      switch (cast_ray(edges, own, p, std::cos(a), std::sin(a), params)) {
        case Vote::own:
          ++own_edge;
          break;
        case Vote::covered:
          ++covered;
          break;
        case Vote::none:
          break;
      }
    }
    out.covered_votes += covered;
    out.own_votes += own_edge;
    sum += own_edge + covered > 0 ? static_cast<double>(own_edge) / (own_edge + covered) : 1.0;
  }
  out.visible = sum / samples;
  return out;
}

std::string GraspFeature::validate() const {
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(point_mm[i]) || !std::isfinite(approach[i])) return "point and approach must be finite";
  if (!(radius_mm > 0 && radius_mm <= 100)) return "radius_mm must be in (0, 100]";
  if (!(max_tilt_deg >= 0 && max_tilt_deg <= 180)) return "max_tilt_deg must be in [0, 180]";
  return {};
}

bool grasp_faces_camera(const GraspFeature& feature, const RigidPose& pose) {
  const double n = cv::norm(feature.approach);
  if (n == 0) return true;
  const cv::Vec3d a = pose.R * (feature.approach / n);
  const cv::Vec3d g = pose.R * feature.point_mm + pose.t_mm;
  const double gn = cv::norm(g);
  if (gn == 0) return false;
  const double cos_tilt = -a.dot(g) / gn;  // against the ray from the camera to the spot
  return cos_tilt >= std::cos(feature.max_tilt_deg * std::numbers::pi / 180.0);
}

GraspVisibility grasp_feature_visibility(const DepthEdges& edges, const TemplateDatabase& db,
                                         const PinholeCamera& camera, const RigidPose& pose,
                                         const GraspFeature& feature, double own_tolerance_px, cv::Mat1b& own,
                                         const GraspVisibilityParams& params) {
  GraspVisibility out;
  if (!grasp_faces_camera(feature, pose)) {
    out.visible = 0;
    out.faces_camera = false;
    return out;
  }
  const cv::Vec3d g = pose.R * feature.point_mm + pose.t_mm;
  if (g[2] <= 0) {
    out.visible = 0;  // behind the camera
    return out;
  }
  if (edges.edges.empty() || edges.shadow.empty()) return out;
  if (own.size() != edges.edges.size()) own = cv::Mat1b::zeros(edges.edges.size());
  RigidPose at = pose;  // nearest_view may turn it onto the view's symmetric copy (the same placed part)
  const int view_index = TemplatePoseFit::nearest_view(db, camera, at);
  const TemplateView& view = db.views[static_cast<size_t>(view_index)];
  const double turn = TemplatePoseFit::in_plane_angle(db, view_index, at, camera);
  // The part's own edges: its projected points with the tolerance around them, each pixel
  // holding the point's oriented tangent at the pose; cleared again afterwards.
  const int tol = static_cast<int>(std::ceil(own_tolerance_px));
  auto stamp = [&](bool set) {
    for (const TemplateEdgePoint& p : view.points) {
      const cv::Vec3d cam = at.R * cv::Vec3d(p.model_mm[0], p.model_mm[1], p.model_mm[2]) + at.t_mm;
      if (cam[2] <= 0) continue;
      const cv::Point2d q = camera.project(cam);
      if (!(std::abs(q.x) < 1e6 && std::abs(q.y) < 1e6)) continue;
      const unsigned char value = set ? encode_own_direction(p.direction + turn) : 0;
      const int cx = static_cast<int>(std::lround(q.x)), cy = static_cast<int>(std::lround(q.y));
      for (int y = std::max(0, cy - tol); y <= std::min(own.rows - 1, cy + tol); ++y)
        for (int x = std::max(0, cx - tol); x <= std::min(own.cols - 1, cx + tol); ++x) own(y, x) = value;
    }
  };
  stamp(true);
  out = grasp_visibility(edges, own, camera.project(g), feature.radius_mm * camera.fx() / g[2], params);
  stamp(false);
  return out;
}

}  // namespace mfcd::vision
