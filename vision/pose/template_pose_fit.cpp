#include "vision/pose/template_pose_fit.hpp"

#include "vision/pose/model_edges.hpp"
#include "vision/pose/rigid_transform.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

namespace mfcd::vision {

void TemplateFitParams::validate() const {
  auto fail = [](const char* field, const char* why) {
    throw std::invalid_argument(std::string("template fit: ") + field + " " + why);
  };
  if (max_points < 12) fail("max_points", "must be >= 12");
  if (iterations < 0) fail("iterations", "must be >= 0");
  if (!(final_gate_px > 0) || !(initial_gate_px >= final_gate_px)) fail("gates", "need initial >= final > 0");
  if (!(huber_px > 0)) fail("huber_px", "must be positive");
  if (!(damping >= 0)) fail("damping", "must be >= 0");
  if (!(score_gate_px > 0) || !(inlier_cost_px > 0)) fail("score_gate_px/inlier_cost_px", "must be positive");
  if (!(lambda_px_per_rad >= 0)) fail("lambda_px_per_rad", "must be >= 0");
  if (min_correspondences < 6) fail("min_correspondences", "must be >= 6");
}

TemplatePoseFit::TemplatePoseFit(const TemplateFitParams& params) : params_(params) { params_.validate(); }

void TemplatePoseFit::prepare(const DepthEdges& edges) {
  if (edges.edges.empty() || edges.edges.type() != CV_8UC1)
    throw std::invalid_argument("template fit: the edge map must be a non-empty 8-bit image");
  chain_edges_.edges = edges.edges;  // shared, not copied
  edges_ = edges.edges;
  // Depth edges say which side is the occluder; the templates' points carry it too
  // (TemplateEdgePoint::direction), so a point only pairs with an edge whose near side is the
  // part's. Intensity edges (no shadow map) are matched undirected.
  // (edge_tangents refuses a shadow map of another size.)
  const bool oriented = !edges.shadow.empty();
  edge_tangents(edges.edges, chain_edges_.direction, 3, oriented ? &edges.shadow : nullptr);
  index_.build(chain_edges_, "template fit: edge map", oriented);
}

void TemplatePoseFit::share_prepared(const TemplatePoseFit& other) {
  chain_edges_ = other.chain_edges_;  // cv::Mat headers
  edges_ = other.edges_;
  index_ = other.index_;
}

namespace {

// The in-plane angle by which the image of the part at `pose` is turned relative to the
// template view's image (as placement_of measures it).
double in_plane_angle(const TemplateDatabase& db, int view, const RigidPose& pose, const PinholeCamera& camera) {
  const cv::Vec3d c = pose.R * db.center_mm + pose.t_mm;
  const cv::Matx33d Rz = ray_alignment(camera, camera.project(c)).t() * pose.R * db.views[view].R_m2c.t();
  return std::atan2(Rz(1, 0), Rz(0, 0));
}

// The offset `profile` gives an edge of oriented tangent `direction` (image radians), as a vector
// along the edge's normal into the shadow.
cv::Vec2d outline_shift(const EdgeOffsetProfile& profile, double direction) {
  const double d = profile.at(direction + std::numbers::pi / 2);
  return cv::Vec2d(-std::sin(direction) * d, std::cos(direction) * d);
}

// A template point's detected-edge offset in its view: its pixel minus its model point's projection
// at the view's pose. A detected depth edge lies off the projected silhouette point by a fraction
// of a pixel to about one (on the shadow side); carried along so that the fit does not shrink or
// grow the part (i.e. move it in depth) to close that gap. With `views_profile` (the edge offset
// correction) the offset is taken to the true outline: the view's own extractor bias for the
// point's direction removed, the query's then added where the point lands (PointPlacer); the two
// differ by up to ~0.4 px when the part turns in the image.
cv::Vec2d view_edge_offset(const TemplateView& tv, const TemplateEdgePoint& p, const PinholeCamera& camera,
                           const EdgeOffsetProfile* views_profile) {
  const cv::Vec3d X(p.model_mm[0], p.model_mm[1], p.model_mm[2]);
  const cv::Point2d seen = camera.project(tv.R_m2c * X + tv.t_m2c_mm) - cv::Point2d(camera.cx(), camera.cy());
  cv::Vec2d offset(p.pixel.x - seen.x, p.pixel.y - seen.y);
  if (views_profile) offset -= outline_shift(*views_profile, p.direction);
  return offset;
}

// The loaded view's points at a pose, in the image (score, fit and compare all place them so):
// each point's projection plus its detected-edge offset, and its tangent angle, both turned by the
// in-plane angle between the view and the pose.
class PointPlacer {
 public:
  // `period`: 2 pi with oriented tangents (an oriented index), else pi.
  // `query_offset`: the query's edge offset profile when the fit corrects for it (load_view took
  // the views' own profile out of the offsets), else null.
  PointPlacer(const TemplatePoseFit::Workspace& ws, const RigidPose& pose, const PinholeCamera& camera, double turn,
              double period, const EdgeOffsetProfile* query_offset)
      : ws_(ws),
        pose_(pose),
        camera_(camera),
        turn_(turn),
        period_(period),
        ct_(std::cos(turn)),
        st_(std::sin(turn)),
        query_offset_(query_offset) {}
  // Point i's image position `at`, its offset there `shift` (at = projection + shift) and its
  // tangent angle in [0, period); false when it lies behind the camera.
  bool place(size_t i, cv::Point2d& at, cv::Point2d& shift, double& angle) const {
    const cv::Vec3d p = pose_.R * ws_.model[i] + pose_.t_mm;
    if (p[2] <= 1e-6) return false;
    angle = std::fmod(ws_.angle[i] + turn_, period_);
    if (angle < 0) angle += period_;
    const cv::Vec2d& o = ws_.offset[i];
    shift = cv::Point2d(ct_ * o[0] - st_ * o[1], st_ * o[0] + ct_ * o[1]);
    if (query_offset_) {
      // Where the query's extractor puts an edge of this direction.
      const cv::Vec2d q = outline_shift(*query_offset_, angle);
      shift += cv::Point2d(q[0], q[1]);
    }
    at = camera_.project(p) + shift;
    return true;
  }

 private:
  const TemplatePoseFit::Workspace& ws_;
  const RigidPose& pose_;
  const PinholeCamera& camera_;
  double turn_, period_, ct_, st_;
  const EdgeOffsetProfile* query_offset_;
};

}  // namespace

double TemplatePoseFit::in_plane_angle(const TemplateDatabase& db, int view, const RigidPose& pose,
                                       const PinholeCamera& camera) {
  return vision::in_plane_angle(db, view, pose, camera);
}

int TemplatePoseFit::nearest_view(const TemplateDatabase& db, const PinholeCamera& /*camera*/, RigidPose& pose) {
  if (db.views.empty()) throw std::invalid_argument("template fit: the database has no views");
  const cv::Vec3d c = pose.R * db.center_mm + pose.t_mm;
  const double n = cv::norm(c);
  if (!(n > 0)) throw std::invalid_argument("template fit: the part centre is at the camera");
  // Direction from the part centre towards the camera, in the model frame.
  const cv::Vec3d d = pose.R.t() * (-c / n);
  // The symmetric copies R S of the pose, S a turn about z the views were folded by (which may be
  // finer than the part's symmetry): continuous, the one turn that puts d in the views' meridian;
  // discrete, the order's turns (computed, not listed: this runs per fit iteration on the frame
  // path).
  int turns = 1;
  double first = 0, step = 0;
  if (db.views_symmetry.kind == PartSymmetry::Kind::continuous_z) {
    double meridian = 0;
    for (const auto& v : db.views)
      if (std::hypot(v.view_direction[0], v.view_direction[1]) > 1e-6) {
        meridian = std::atan2(v.view_direction[1], v.view_direction[0]);
        break;
      }
    first = std::atan2(d[1], d[0]) - meridian;
  } else if (db.views_symmetry.kind == PartSymmetry::Kind::discrete_z) {
    turns = std::max(1, db.views_symmetry.order);
    step = 2 * std::numbers::pi / turns;
  }
  int best_view = 0;
  double best_dot = -2;
  cv::Matx33d best_turn = cv::Matx33d::eye();
  for (int k = 0; k < turns; ++k) {
    const cv::Matx33d S = rotation_about_z(first + k * step);
    // The copy R S of the pose sees the part from S^T d.
    const cv::Vec3d ds = S.t() * d;
    for (int v = 0; v < static_cast<int>(db.views.size()); ++v) {
      const double dot = ds.dot(db.views[v].view_direction);
      if (dot > best_dot) best_dot = dot, best_view = v, best_turn = S;
    }
  }
  const cv::Matx33d& S = best_turn;
  // Same placed part: rotated by S about the symmetry axis through the centre.
  // (Computed into locals first: assigning a braced temporary built from `pose` itself let
  // GCC 12 construct it in place, overwriting R while it was still being read.)
  const cv::Matx33d R = pose.R * S;
  const cv::Vec3d t = pose.t_mm + pose.R * (db.center_mm - S * db.center_mm);
  pose.R = R;
  pose.t_mm = t;
  return best_view;
}

const EdgeOffsetProfile* TemplatePoseFit::query_offset(const TemplateDatabase& db) const {
  // Depth edges only (the profiles are the depth-edge extractor's; intensity edges are matched
  // undirected), and only with both profiles (version 3 files have none).
  if (!params_.edge_offset_correction || !index_.oriented()) return nullptr;
  if (db.template_edge_offset.empty() || db.query_edge_offset.empty()) return nullptr;
  return &db.query_edge_offset;
}

void TemplatePoseFit::reserve(const TemplateDatabase& db, cv::Size image, Workspace& ws) const {
  size_t points = 0;
  for (const auto& v : db.views) points = std::max(points, v.points.size());
  // compare() loads every point of a view; fit() and score() at most params_.max_points.
  for (auto* v : {&ws.seen_a, &ws.seen_b}) v->reserve(points);
  for (auto* v : {&ws.angle_a, &ws.angle_b}) v->reserve(points);
  ws.model.reserve(points);
  ws.angle.reserve(points);
  ws.offset.reserve(points);
  ws.placed.reserve(points);
  ws.region.reserve(points, image.height);
  if (ws.explained.size() != image) ws.explained = cv::Mat1b::zeros(image);
}

void TemplatePoseFit::load_view(const TemplateDatabase& db, int view, const PinholeCamera& camera, Workspace& ws,
                                int max_points) const {
  // The one range check of fit(), evaluate() and compare(): each loads its views through here
  // before reading anything else of them.
  if (view < 0 || view >= static_cast<int>(db.views.size()))
    throw std::invalid_argument("template fit: view " + std::to_string(view) + " out of range");
  const TemplateView& tv = db.views[static_cast<size_t>(view)];
  const auto& pts = tv.points;
  ws.model.clear();
  ws.angle.clear();
  ws.offset.clear();
  const size_t n = pts.size();
  const size_t keep = std::min<size_t>(n, static_cast<size_t>(max_points > 0 ? max_points : params_.max_points));
  const EdgeOffsetProfile* views_profile = query_offset(db) ? &db.template_edge_offset : nullptr;
  for (size_t k = 0; k < keep; ++k) {
    const auto& p = pts[k * n / keep];
    ws.model.emplace_back(p.model_mm[0], p.model_mm[1], p.model_mm[2]);
    ws.angle.push_back(p.direction);
    ws.offset.push_back(view_edge_offset(tv, p, camera, views_profile));
  }
}

double point_to_line_residual(const RigidPose& pose, const cv::Vec3d& centre_cam, const cv::Vec3d& model_point,
                              const PinholeCamera& camera, const cv::Point2d& edge, const cv::Vec2d& normal,
                              cv::Matx16d* jacobian) {
  const cv::Vec3d p = pose.R * model_point + pose.t_mm;
  const double iz = 1.0 / p[2];
  const double u = camera.fx() * p[0] * iz + camera.cx(), v = camera.fy() * p[1] * iz + camera.cy();
  const double r = normal[0] * (u - edge.x) + normal[1] * (v - edge.y);
  if (jacobian) {
    // d(u, v)/dp, then dp/dw = -[p - c]x (rotation about the centre), dp/dtau = I.
    const double gx = normal[0] * camera.fx() * iz, gy = normal[1] * camera.fy() * iz;
    const double gz = -(normal[0] * camera.fx() * p[0] + normal[1] * camera.fy() * p[1]) * iz * iz;
    const cv::Vec3d g(gx, gy, gz);  // dr/dp
    const cv::Vec3d a = p - centre_cam;
    const cv::Vec3d gw = a.cross(g);  // dr/dw = g^T (-[a]x) = (a x g)^T
    *jacobian = cv::Matx16d(gw[0], gw[1], gw[2], g[0], g[1], g[2]);
  }
  return r;
}

RigidPose apply_pose_update(const RigidPose& pose, const cv::Vec3d& centre_model, const cv::Vec6d& update) {
  const cv::Vec3d c = pose.R * centre_model + pose.t_mm;
  RigidPose out;
  out.R = rotation_from_angle_axis({update[0], update[1], update[2]}) * pose.R;
  const cv::Vec3d c1 = c + cv::Vec3d(update[3], update[4], update[5]);
  out.t_mm = c1 - out.R * centre_model;
  return out;
}

void TemplatePoseFit::score(const TemplateDatabase& db, int view, const PinholeCamera& camera, Workspace& ws,
                            TemplateFitResult& r) const {
  const PointPlacer placer(ws, r.pose, camera, in_plane_angle(db, view, r.pose, camera), period(), query_offset(db));
  const double gate = params_.score_gate_px;
  double sum = 0;
  int inliers = 0, count = 0;
  for (size_t i = 0; i < ws.model.size(); ++i) {
    double cost = gate;  // a point behind the camera counts as unmatched
    cv::Point2d q, shift;
    double a;
    if (placer.place(i, q, shift, a)) {
      const EdgeMatch m = index_.nearest(q, a, params_.lambda_px_per_rad, gate);
      if (m.found) cost = m.cost;
    }
    sum += cost;
    inliers += cost <= params_.inlier_cost_px;
    ++count;
  }
  r.points = count;
  r.mean_cost_px = count ? sum / count : gate;
  r.inlier_fraction = count ? double(inliers) / count : 0;
  r.score = std::clamp(r.inlier_fraction * (1.0 - r.mean_cost_px / gate), 0.0, 1.0);
  r.coverage = coverage(db, view, r.pose, camera, ws);
}

double TemplatePoseFit::coverage(const TemplateDatabase& db, int view, const RigidPose& pose,
                                 const PinholeCamera& camera, Workspace& ws) const {
  const cv::Size size = edges_.size();
  if (ws.explained.size() != size) ws.explained = cv::Mat1b::zeros(size);
  const TemplateView& tv = db.views[static_cast<size_t>(view)];
  const double turn = in_plane_angle(db, view, pose, camera);
  const double ct = std::cos(turn), st = std::sin(turn);
  const cv::Rect image(cv::Point(0, 0), size);
  const EdgeOffsetProfile* profile = query_offset(db);
  const EdgeOffsetProfile* views_profile = profile ? &db.template_edge_offset : nullptr;
  ws.placed.clear();
  for (const auto& p : tv.points) {
    const cv::Vec3d X(p.model_mm[0], p.model_mm[1], p.model_mm[2]);
    const cv::Vec3d c = pose.R * X + pose.t_mm;
    if (c[2] <= 1e-6) continue;
    // The same edge offsets as the fit's points (view_edge_offset, PointPlacer).
    const cv::Vec2d o = view_edge_offset(tv, p, camera, views_profile);
    cv::Point2d extra(0, 0);
    if (profile) {
      const cv::Vec2d theirs = outline_shift(*profile, p.direction + turn);
      extra = cv::Point2d(theirs[0], theirs[1]);
    }
    const cv::Point2d q = camera.project(c) + cv::Point2d(ct * o[0] - st * o[1], st * o[0] + ct * o[1]) + extra;
    const cv::Point r(cvRound(q.x), cvRound(q.y));
    if (image.contains(r)) ws.placed.push_back(r);
  }
  return explained_edge_fraction(edges_, ws.placed, ws.region, ws.explained);
}

namespace {
// The pixels cv::circle(image, c, 2, 255, cv::FILLED) sets around c, as offsets from c: drawn once
// by cv::circle itself, so the stamp is its disc exactly. Stamping them by hand costs a tenth of
// what a thousand cv::circle calls per hypothesis did (argument checks, colour conversion, trace
// regions: ~2 % of a cycle).
struct DiscStamp {
  static constexpr int kRadius = 2;
  int count = 0;
  cv::Point offset[(2 * kRadius + 1) * (2 * kRadius + 1)];
};
const DiscStamp& radius_two_disc() {
  static const DiscStamp disc = [] {
    constexpr int r = DiscStamp::kRadius, side = 2 * r + 1;
    cv::Mat1b m = cv::Mat1b::zeros(side, side);
    cv::circle(m, cv::Point(r, r), r, cv::Scalar(255), cv::FILLED);
    DiscStamp d;
    for (int y = 0; y < side; ++y)
      for (int x = 0; x < side; ++x)
        if (m(y, x)) d.offset[d.count++] = cv::Point(x - r, y - r);
    return d;
  }();
  return disc;
}
}  // namespace

double explained_edge_fraction(const cv::Mat1b& edges, const std::vector<cv::Point>& placed, ConvexRegion& region,
                               cv::Mat1b& explained) {
  if (placed.size() < 3) return 0;
  region.build(placed);
  const DiscStamp& disc = radius_two_disc();
  constexpr int r = DiscStamp::kRadius;
  for (const auto& c : placed) {
    // The disc clipped to the image, as cv::circle clips it.
    const bool inside = c.x >= r && c.y >= r && c.x < explained.cols - r && c.y < explained.rows - r;
    for (int k = 0; k < disc.count; ++k) {
      const cv::Point p = c + disc.offset[k];
      if (inside || (p.x >= 0 && p.y >= 0 && p.x < explained.cols && p.y < explained.rows)) explained(p) = 255;
    }
  }
  int total = 0, covered = 0;
  for (int y = std::max(region.top(), 0); y <= std::min(region.bottom(), edges.rows - 1); ++y) {
    const uint8_t* e = edges.ptr<uint8_t>(y);
    const uint8_t* ex = explained.ptr<uint8_t>(y);
    for (int x = std::max(region.first(y), 0); x <= std::min(region.last(y), edges.cols - 1); ++x)
      if (e[x]) ++total, covered += ex[x] != 0;
  }
  // Clear the discs again: they lie within 2 px of the hull's bounding box (set by hand,
  // Mat::setTo allocates).
  int x0 = region.hull()[0].x, x1 = x0;
  for (const auto& p : region.hull()) x0 = std::min(x0, p.x), x1 = std::max(x1, p.x);
  const cv::Rect box = cv::Rect(cv::Point(x0 - 2, region.top() - 2), cv::Point(x1 + 3, region.bottom() + 3)) &
                       cv::Rect(cv::Point(0, 0), explained.size());
  for (int y = box.y; y < box.y + box.height; ++y) std::fill_n(explained.ptr<uint8_t>(y) + box.x, box.width, 0);
  return total > 0 ? double(covered) / total : 0;
}

TemplateFitResult TemplatePoseFit::evaluate(const TemplateDatabase& db, int view, const RigidPose& pose,
                                            const PinholeCamera& camera, Workspace& ws, int max_points) const {
  TemplateFitResult r;
  r.pose = pose;
  r.view = view;
  load_view(db, view, camera, ws, max_points);
  score(db, view, camera, ws, r);
  return r;
}

double TemplatePoseFit::gate_at(int step) const {
  const int steps = params_.iterations;
  const double f = steps > 1 ? double(step) / (steps - 1) : 1.0;
  return params_.initial_gate_px * std::pow(params_.final_gate_px / params_.initial_gate_px, f);
}

bool TemplatePoseFit::solve_step(cv::Matx66d H, const cv::Vec6d& g, cv::Vec6d& delta) const {
  for (int k = 0; k < 6; ++k) H(k, k) += params_.damping * H(k, k) + 1e-9;
  return cv::solve(H, -g, delta, cv::DECOMP_CHOLESKY);
}

TemplateFitResult TemplatePoseFit::fit(const TemplateDatabase& db, int view, const RigidPose& initial,
                                       const PinholeCamera& camera, Workspace& ws) const {
  TemplateFitResult r;
  r.pose = initial;
  r.view = view;
  load_view(db, view, camera, ws);
  const int steps = params_.iterations;
  for (int it = 0; it < steps; ++it) {
    const double gate = gate_at(it);
    const cv::Vec3d centre = r.pose.R * db.center_mm + r.pose.t_mm;
    cv::Matx66d H = cv::Matx66d::zeros();
    cv::Vec6d g(0, 0, 0, 0, 0, 0);
    const int n = accumulate(db, r.view, r.pose, centre, camera, gate, ws, nullptr, H, g);
    if (n < params_.min_correspondences) break;
    cv::Vec6d delta;
    if (!solve_step(H, g, delta)) break;
    r.pose = apply_pose_update(r.pose, db.center_mm, delta);
    r.iterations = it + 1;
    // Turned nearer to another view: continue with its points.
    RigidPose moved = r.pose;
    const int nearest = nearest_view(db, camera, moved);
    if (nearest != r.view) {
      r.pose = moved;
      r.view = nearest;
      load_view(db, r.view, camera, ws);
    }
  }
  if (params_.score_result) score(db, r.view, camera, ws, r);
  return r;
}

int TemplatePoseFit::accumulate(const TemplateDatabase& db, int view, const RigidPose& pose,
                                const cv::Vec3d& centre_cam, const PinholeCamera& camera, double gate,
                                const Workspace& ws, const cv::Matx33d* update_to_camera, cv::Matx66d& H,
                                cv::Vec6d& g) const {
  const PointPlacer placer(ws, pose, camera, in_plane_angle(db, view, pose, camera), period(), query_offset(db));
  int n = 0;
  for (size_t i = 0; i < ws.model.size(); ++i) {
    cv::Point2d at, shift;
    double a;
    if (!placer.place(i, at, shift, a)) continue;
    const EdgeMatch m = index_.nearest(at, a, params_.lambda_px_per_rad, gate);
    if (!m.found) continue;
    const cv::Vec2d normal(-std::sin(m.angle), std::cos(m.angle));
    cv::Matx16d J;
    const double res =
        point_to_line_residual(pose, centre_cam, ws.model[i], camera, cv::Point2d(m.x, m.y) - shift, normal, &J);
    if (update_to_camera) {
      // The update is another camera's: its rotation and translation turn into this one's by R.
      const cv::Matx13d Jw = cv::Matx13d(J(0, 0), J(0, 1), J(0, 2)) * *update_to_camera;
      const cv::Matx13d Jt = cv::Matx13d(J(0, 3), J(0, 4), J(0, 5)) * *update_to_camera;
      J = cv::Matx16d(Jw(0, 0), Jw(0, 1), Jw(0, 2), Jt(0, 0), Jt(0, 1), Jt(0, 2));
    }
    const double w = std::abs(res) <= params_.huber_px ? 1.0 : params_.huber_px / std::abs(res);
    H += w * (J.t() * J);
    g += w * res * cv::Vec6d(J.val);
    ++n;
  }
  return n;
}

void TemplatePoseFit::place_points(const TemplateDatabase& db, int view, const RigidPose& pose,
                                   const PinholeCamera& camera, const Workspace& ws, std::vector<cv::Point2d>& seen,
                                   std::vector<double>& angle) const {
  const PointPlacer placer(ws, pose, camera, in_plane_angle(db, view, pose, camera), period(), query_offset(db));
  seen.clear();
  angle.clear();
  for (size_t i = 0; i < ws.model.size(); ++i) {
    cv::Point2d at, shift;
    double a = 0;
    // A point behind the camera stays in the list, outside the image, so that seen[i] is point i.
    if (!placer.place(i, at, shift, a)) at = cv::Point2d(-1e6, -1e6);
    seen.push_back(at);
    angle.push_back(a);
  }
}

TemplatePoseFit::Difference TemplatePoseFit::compare(const TemplateDatabase& db, const TemplateFitResult& a,
                                                     const TemplateFitResult& b, const PinholeCamera& camera,
                                                     Workspace& ws, const std::vector<uint8_t>* differs_a,
                                                     const std::vector<uint8_t>* differs_b, double apart_px) const {
  // Every point of both views (the fit's subsample is too sparse to say which points coincide).
  load_view(db, a.view, camera, ws, kAllPoints);
  place_points(db, a.view, a.pose, camera, ws, ws.seen_a, ws.angle_a);
  load_view(db, b.view, camera, ws, kAllPoints);
  place_points(db, b.view, b.pose, camera, ws, ws.seen_b, ws.angle_b);
  if ((differs_a && differs_a->size() != ws.seen_a.size()) || (differs_b && differs_b->size() != ws.seen_b.size()))
    throw std::invalid_argument("template fit: compare's point flags do not match the views");
  const cv::Size size = edges_.size();
  if (ws.explained.size() != size) ws.explained = cv::Mat1b::zeros(size);
  const cv::Rect image(cv::Point(0, 0), size);
  const int r = std::max(0, static_cast<int>(std::lround(apart_px)));
  const double gate = std::max(kCompareGatePx, params_.inlier_cost_px);
  // The other pose's points, widened by apart_px, as a mask (ws.explained, cleared again after).
  auto only = [&](const std::vector<cv::Point2d>& mine, const std::vector<double>& angle,
                  const std::vector<cv::Point2d>& other, const std::vector<uint8_t>* differs, int& count, double& found,
                  double& cost) {
    cv::Rect touched;
    for (const auto& q : other) {
      const cv::Point c(cvRound(q.x), cvRound(q.y));
      if (!image.contains(c)) continue;
      cv::circle(ws.explained, c, r, cv::Scalar(255), cv::FILLED);
      touched |= cv::Rect(c.x - r, c.y - r, 2 * r + 1, 2 * r + 1);
    }
    int n = 0, on = 0;
    double sum = 0;
    for (size_t i = 0; i < mine.size(); ++i) {
      const cv::Point c(cvRound(mine[i].x), cvRound(mine[i].y));
      if (!image.contains(c)) continue;
      if (ws.explained(c) != 0 || (differs && !(*differs)[i])) continue;
      ++n;
      // One query with the wider gate: the index returns the exact argmin, so the inlier test
      // gives what a query gated at score_gate_px would.
      const EdgeMatch m = index_.nearest(mine[i], angle[i], params_.lambda_px_per_rad, gate);
      on += m.found && m.cost <= params_.inlier_cost_px;
      sum += m.found ? std::min(m.cost, kCompareGatePx) : kCompareGatePx;
    }
    cost = n ? sum / n : kCompareGatePx;
    ws.explained(touched & image).setTo(0);
    count = n;
    found = n ? double(on) / n : 0;
  };
  Difference d;
  only(ws.seen_a, ws.angle_a, ws.seen_b, differs_a, d.only_a, d.found_a, d.cost_a);
  only(ws.seen_b, ws.angle_b, ws.seen_a, differs_b, d.only_b, d.found_b, d.cost_b);
  return d;
}

SurfaceGrid part_surface(const TemplateDatabase& db) { return SurfaceGrid(db.mesh, 0.25, 0.5); }

std::vector<std::vector<uint8_t>> asymmetric_points(const TemplateDatabase& db, const SurfaceGrid& surface,
                                                    const cv::Matx33d& turn, double* share, const cv::Vec3d* pivot_mm) {
  const cv::Vec3d c = pivot_mm ? *pivot_mm : db.center_mm;
  std::vector<std::vector<uint8_t>> out;
  out.reserve(db.views.size());
  size_t flagged = 0, total = 0;
  for (const TemplateView& view : db.views) {
    auto& flags = out.emplace_back(view.points.size(), 0);
    for (size_t i = 0; i < view.points.size(); ++i) {
      const cv::Vec3f& X = view.points[i].model_mm;
      flags[i] = !surface.near(turn * (cv::Vec3d(X[0], X[1], X[2]) - c) + c);
      flagged += flags[i];
    }
    total += view.points.size();
  }
  if (share) *share = total ? double(flagged) / double(total) : 0.0;
  return out;
}

}  // namespace mfcd::vision
