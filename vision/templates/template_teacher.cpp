#include "vision/templates/template_teacher.hpp"

#include "vision/common/rotation.hpp"
#include "vision/edges/edge_tangents.hpp"
#include "vision/templates/render_window.hpp"
#include "vision/templates/view_sampling.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <memory>
#include <mutex>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <thread>

namespace mfcd::vision {

cv::Vec3d part_center(const Mesh& mesh) {
  const cv::Vec3f lo = mesh.bbox_min(), hi = mesh.bbox_max();
  return cv::Vec3d((lo[0] + hi[0]) * 0.5, (lo[1] + hi[1]) * 0.5, (lo[2] + hi[2]) * 0.5);
}

double part_radius(const Mesh& mesh, const cv::Vec3d& center) {
  double r2 = 0;
  for (const auto& v : mesh.vertices) {
    const cv::Vec3d d(v[0] - center[0], v[1] - center[1], v[2] - center[2]);
    r2 = std::max(r2, d.dot(d));
  }
  return std::sqrt(r2);
}

double mesh_diameter(const Mesh& mesh) {
  // The farthest pair of points lies on the convex hull; the hull of a part has far fewer
  // vertices than the part, so the quadratic scan over it is cheap. Hull in 3-D is taken as
  // the vertices extreme along many directions, which contains every hull vertex that is
  // extreme along any of them; the exact pair is then found among all vertices against them.
  if (mesh.vertices.empty()) return 0;
  std::vector<int> extreme;
  for (const auto& d : fibonacci_sphere(512)) {
    int best = 0;
    double bv = -1e300;
    for (size_t i = 0; i < mesh.vertices.size(); ++i) {
      const auto& v = mesh.vertices[i];
      const double p = v[0] * d[0] + v[1] * d[1] + v[2] * d[2];
      if (p > bv) bv = p, best = static_cast<int>(i);
    }
    extreme.push_back(best);
  }
  std::sort(extreme.begin(), extreme.end());
  extreme.erase(std::unique(extreme.begin(), extreme.end()), extreme.end());
  double best = 0;
  for (int e : extreme)
    for (const auto& v : mesh.vertices) {
      const cv::Vec3f d = v - mesh.vertices[e];
      best = std::max(best, static_cast<double>(d.dot(d)));
    }
  return std::sqrt(best);
}

namespace {

struct ViewGeometry {
  cv::Rect window;        // rendered part of the image
  PinholeCamera cropped;  // camera of the window
  double plane_z_mm = 0;
  double plane_size_mm = 0;
};

ViewGeometry view_geometry(const CameraConfig& config, double distance, double radius, double gap) {
  const PinholeCamera& cam = config.camera;
  const double f = std::max(cam.fx(), cam.fy());
  const double near = distance - radius;
  // Image radius of the sphere holding the part, plus the widest shadow any flash can cast on
  // the background.
  const double zb = distance + radius + gap;
  const int half = window_half_px(config, f * radius / near, near, zb);
  const cv::Rect window = window_on_axis(cam, half);
  ViewGeometry g;
  g.window = window;
  g.cropped = cam.cropped(window);
  g.plane_z_mm = zb;
  g.plane_size_mm = 4.0 * (half + 16) / f * zb;
  return g;
}

bool part_pixel_near(const MfcRender& render, int x, int y) {
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) {
      const int xx = x + dx, yy = y + dy;
      if (xx >= 0 && yy >= 0 && xx < render.part_index.cols && yy < render.part_index.rows &&
          render.part_index(yy, xx) == 1)
        return true;
    }
  return false;
}

// The turn about the optical axis that brings the LED ring onto itself: 360 degrees over the
// LED count for a regular ring whose steps close the circle, else a full turn.
double lighting_period(const FlashRing& flashes) {
  if (flashes.ring && flashes.ring->count > 0 &&
      std::abs(std::abs(flashes.ring->step_deg) * flashes.ring->count - 360.0) < 1e-6)
    return 2 * std::numbers::pi / flashes.ring->count;
  return 2 * std::numbers::pi;
}

void drop_background_edges(DepthEdges& edges, const MfcRender& render) {
  for (int y = 0; y < edges.edges.rows; ++y)
    for (int x = 0; x < edges.edges.cols; ++x)
      if (edges.edges(y, x) && !part_pixel_near(render, x, y)) edges.edges(y, x) = 0;
}

// Depth-edge pixels -> model points: the part pixel nearest to the camera within one pixel
// (the occluding side of the discontinuity), back-projected with the cropped camera.
void trace_points(const DepthEdges& edges, const MfcRender& render, const PinholeCamera& cam, const cv::Matx33d& R,
                  const cv::Vec3d& t, const cv::Point2f& origin, TemplateView& view) {
  const cv::Matx33d Rt = R.t();
  // Chain directions, the estimator the pose fits use on the query's edges too.
  cv::Mat1f tangents;  // oriented by the shadow side (TemplateEdgePoint::direction)
  edge_tangents(edges.edges, tangents, 3, &edges.shadow);
  for (int y = 0; y < edges.edges.rows; ++y)
    for (int x = 0; x < edges.edges.cols; ++x) {
      if (!edges.edges(y, x)) continue;
      float best = 0;
      cv::Point at(-1, -1);
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if (xx < 0 || yy < 0 || xx >= edges.edges.cols || yy >= edges.edges.rows) continue;
          if (render.part_index(yy, xx) != 1) continue;
          const float z = render.depth_mm(yy, xx);
          if (z > 0 && (at.x < 0 || z < best)) best = z, at = cv::Point(xx, yy);
        }
      if (at.x < 0) continue;  // an edge with no part pixel next to it (background only)
      const cv::Vec3d pc((at.x - cam.cx()) / cam.fx() * best, (at.y - cam.cy()) / cam.fy() * best, best);
      const cv::Vec3d pm = Rt * (pc - t);
      TemplateEdgePoint p;
      p.pixel = cv::Point2f(static_cast<float>(x), static_cast<float>(y)) - origin;
      p.direction = tangents(y, x);
      p.model_mm = cv::Vec3f(static_cast<float>(pm[0]), static_cast<float>(pm[1]), static_cast<float>(pm[2]));
      view.points.push_back(p);
    }
}

// Throws std::invalid_argument naming the first bad input.
void validate_teach_inputs(const Mesh& mesh, const TeachParams& params) {
  if (params.sphere_samples < 1 || params.sphere_samples > 100000)
    throw std::invalid_argument("sphere samples K = " + std::to_string(params.sphere_samples) +
                                " out of range [1, 100000]");
  if (mesh.vertices.empty() || mesh.triangles.empty()) throw std::invalid_argument("teach: the mesh is empty");
  if (params.lighting_turns < 1 || params.lighting_turns > 64 || params.lighting_min_turns < 1 ||
      params.lighting_min_turns > params.lighting_turns)
    throw std::invalid_argument("teach: lighting turns " + std::to_string(params.lighting_min_turns) + " of " +
                                std::to_string(params.lighting_turns) + " need 1 <= min <= turns <= 64");
  if (params.lighting_tolerance_px < 0 || params.lighting_tolerance_px > 10)
    throw std::invalid_argument("teach: lighting tolerance " + std::to_string(params.lighting_tolerance_px) +
                                " px out of range [0, 10]");
  if (params.lighting_band_px < 0 || params.lighting_band_px > 100)
    throw std::invalid_argument("teach: lighting band " + std::to_string(params.lighting_band_px) +
                                " px out of range [0, 100]");
}

// What the views share: the part, where it stands, the window and its background plane.
struct TeachSetup {
  const Mesh& mesh;
  const CameraConfig& camera;
  const TeachParams& params;
  LineFitParams lines;
  ViewGeometry geo;
  Mesh plane;
  double distance_mm = 0;
  cv::Vec3d center_mm;
  double turn_period = 0;  // the LED ring's, rad
};

// One teaching worker's renderer, extractor and buffers (its own GL context): a view from a
// direction, allocating only for what it returns once its buffers have their sizes.
class ViewTeacher {
 public:
  explicit ViewTeacher(const TeachSetup& setup)
      : s_(setup),
        renderer_(setup.camera, template_render_options()),
        extractor_(setup.geo.cropped, setup.camera.flashes, setup.params.edges) {
    renderer_.set_camera(s_.geo.cropped);
    part_id_ = renderer_.add_mesh(s_.mesh);
    plane_id_ = renderer_.add_mesh(s_.plane);
    const int k = 2 * s_.params.lighting_tolerance_px + 1;
    tolerance_kernel_ = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(k, k));
    const int b = 2 * s_.params.lighting_band_px + 1;
    band_kernel_ = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(b, b));
  }

  // The view from `direction`, or nothing when it shows too few edges to fit.
  std::optional<TemplateView> teach(const cv::Vec3d& direction) {
    TemplateView view;
    view.view_direction = direction;
    view.R_m2c = view_rotation(direction);
    view.t_m2c_mm = placed(view.R_m2c);
    render_edges(view.R_m2c, render_, edges_);
    if (s_.params.lighting_turns > 1) keep_edges_every_turn_shows(view.R_m2c);
    if (cv::countNonZero(edges_.edges) < s_.params.min_edge_pixels) return std::nullopt;
    LineFitResult fit = fitLines(edges_.edges, s_.lines, &edges_.direction, &edges_.shadow);
    if (fit.set.lines.empty()) return std::nullopt;
    const cv::Point2f origin(static_cast<float>(s_.geo.cropped.cx()), static_cast<float>(s_.geo.cropped.cy()));
    view.lines = std::move(fit.set);
    view.lines.origin = origin;
    trace_points(edges_, render_, s_.geo.cropped, view.R_m2c, view.t_m2c_mm, origin, view);
    if (view.points.empty()) return std::nullopt;
    view.box = cv::Rect2f(view.points.front().pixel, cv::Size2f(1.f, 1.f));
    for (const auto& p : view.points) view.box |= cv::Rect2f(p.pixel, cv::Size2f(1.f, 1.f));
    return view;
  }

 private:
  static RenderOptions template_render_options() {
    RenderOptions options;
    options.noise.enabled = false;  // templates are the ideal appearance; the query carries the noise
    options.deferred_shading = true;
    return options;
  }

  // The part centre on the optical axis at the teaching distance.
  cv::Vec3d placed(const cv::Matx33d& R) const { return cv::Vec3d(0, 0, s_.distance_mm) - R * s_.center_mm; }

  // The depth edges of the part turned by R in front of the background plane, drawn in `region`
  // (empty: where the part and its shadows can show, part_region).
  void render_edges(const cv::Matx33d& R, MfcRender& render, DepthEdges& edges, const Lighting& lighting = {},
                    cv::Rect region = {}) {
    const cv::Vec3d t = placed(R);
    const ScenePart parts[2] = {
        {part_id_, R, t, Material::matte(0.7f)},
        {plane_id_, cv::Matx33d::eye(), cv::Vec3d(0, 0, s_.geo.plane_z_mm), Material::matte(0.6f), false}};
    if (region.empty() && !s_.params.render_whole_window)
      region = part_region(s_.camera, s_.geo.cropped, s_.mesh, R, t, s_.geo.plane_z_mm);
    region_ = region;
    renderer_.render(parts, render, 1, region, lighting);
    extractor_.extract(render.frames, edges);
    // Edges with no part pixel next to them are features of the shadows on the template's
    // background plane (where two flashes' shadows meet), not of the part: a bin floor at
    // another distance would not show them, so they are removed before line fitting.
    drop_background_edges(edges, render);
  }

  // The view lit by the LED ring turned about the optical axis: an edge that the turns do not all
  // show depends on where the LEDs stand around the part, and the query's part stands at any
  // turn. Turning the ring the opposite way is turning the part, seen in the view's own pixels.
  // A turned render lights only the pixels within lighting_band_px of the view's edges (0: all):
  // an edge farther away cannot confirm one of them.
  void keep_edges_every_turn_shows(const cv::Matx33d& R_view) {
    const TeachParams& params = s_.params;
    Lighting lighting;
    cv::Rect region;  // the view's (its surfaces are lit again)
    if (params.lighting_band_px > 0) {
      cv::dilate(edges_.edges, band_, band_kernel_);
      lighting.lit = &band_;
      const cv::Rect view_region = region_.empty() ? cv::Rect(cv::Point(), band_.size()) : region_;
      region = cv::boundingRect(band_) & view_region;
      if (region.empty()) return;  // no edge to check
    }
    support_.create(edges_.edges.size());
    support_.setTo(1);  // the view itself
    for (int k = 1; k < params.lighting_turns; ++k) {
      lighting.ring_turn_rad = -s_.turn_period * k / params.lighting_turns;
      render_edges(R_view, turned_render_, turned_edges_, lighting, region);
      cv::dilate(turned_edges_.edges, turned_near_, tolerance_kernel_);
      cv::add(support_, 1, support_, turned_near_);
    }
    edges_.edges.setTo(0, support_ < params.lighting_min_turns);
  }

  const TeachSetup& s_;
  MfcRenderer renderer_;
  DepthEdgeExtractor extractor_;
  int part_id_ = -1, plane_id_ = -1;
  cv::Rect region_;  // of the last render_edges (empty: the whole window)
  cv::Mat tolerance_kernel_, band_kernel_;
  MfcRender render_, turned_render_;
  DepthEdges edges_, turned_edges_;
  cv::Mat1b band_, turned_near_, support_;
};

// Runs `work(i)` for i in [0, total) on `threads` threads, each with its own `State` made by
// `make_state()` on that thread; reports progress after each; the first exception stops the
// rest and is rethrown.
template <typename MakeState, typename Work>
void for_each_view(int total, int threads, const TeachProgress& progress, MakeState make_state, Work work) {
  std::atomic<int> next{0};
  int done = 0;
  std::mutex mutex;
  std::exception_ptr error;
  threads = std::clamp(threads, 1, std::max(1, total));
  auto worker = [&]() {
    try {
      auto state = make_state();
      for (int i = next++; i < total; i = next++) {
        work(*state, i);
        std::lock_guard<std::mutex> lock(mutex);
        ++done;
        if (progress) progress(done, total);
      }
    } catch (...) {
      std::lock_guard<std::mutex> lock(mutex);
      if (!error) error = std::current_exception();
      next = total;
    }
  };
  std::vector<std::thread> pool;
  for (int k = 1; k < threads; ++k) pool.emplace_back(worker);
  worker();
  for (auto& th : pool) th.join();
  if (error) std::rethrow_exception(error);
}

}  // namespace

TemplateDatabase teach_templates(const Mesh& mesh, const CameraConfig& camera, const std::string& part_name, int obj_id,
                                 const TeachParams& params, const TeachProgress& progress) {
  validate_camera_config(camera, "teach camera");
  // Templates always carry edge polarity (the view's shadow side is known exactly); a pipeline
  // that searches without it drops it when it loads them (withoutPolarity).
  LineFitParams line_params = params.lines;
  line_params.oriented = true;
  line_params.validate();
  validate_teach_inputs(mesh, params);

  TemplateDatabase db;
  db.part_name = part_name;
  db.obj_id = obj_id;
  db.symmetry = params.symmetry;
  db.views_symmetry = params.views_symmetry.value_or(params.symmetry);
  if (!db.symmetry.includes(db.views_symmetry))
    throw std::invalid_argument("teach: views symmetry " + db.views_symmetry.str() +
                                " is not a symmetry of the part (" + db.symmetry.str() + ")");
  db.camera = camera;
  db.center_mm = part_center(mesh);
  db.diameter_mm = mesh_diameter(mesh);
  db.sphere_samples = params.sphere_samples;
  db.q = 2 * line_params.q;
  db.oriented = true;
  db.mesh = mesh;
  const double radius = part_radius(mesh, db.center_mm);
  db.distance_mm = params.distance_mm > 0 ? params.distance_mm : camera.working_distance_mm;
  if (db.distance_mm < 2 * radius)
    throw std::invalid_argument("teach: distance " + std::to_string(db.distance_mm) +
                                " mm is too close for a part of radius " + std::to_string(radius) + " mm");

  const std::vector<cv::Vec3d> directions = template_view_directions(params.sphere_samples, db.views_symmetry);
  const ViewGeometry geo = view_geometry(camera, db.distance_mm, radius, params.background_gap_mm);
  const TeachSetup setup{.mesh = mesh,
                         .camera = camera,
                         .params = params,
                         .lines = line_params,
                         .geo = geo,
                         .plane = make_plane(geo.plane_size_mm),
                         .distance_mm = db.distance_mm,
                         .center_mm = db.center_mm,
                         .turn_period = lighting_period(camera.flashes)};
  const int total = static_cast<int>(directions.size());
  std::vector<std::optional<TemplateView>> views(total);
  const int threads = params.threads > 0 ? params.threads : static_cast<int>(std::thread::hardware_concurrency());
  for_each_view(
      total, threads, progress, [&] { return std::make_unique<ViewTeacher>(setup); },
      [&](ViewTeacher& teacher, int i) { views[i] = teacher.teach(directions[i]); });

  for (auto& v : views)
    if (v) {
      v->index = static_cast<int>(db.views.size());
      db.views.push_back(std::move(*v));
    }
  if (db.views.empty())
    throw std::runtime_error("teach '" + part_name + "': no view produced depth edges (is the part inside the image?)");
  if (params.edge_offset_profiles) {
    // The views are rendered without noise over a plane background_gap_mm behind the part.
    EdgeProfileConditions views_conditions;
    views_conditions.noise = false;
    views_conditions.floor_gap_mm = params.background_gap_mm;
    db.template_edge_offset = measure_edge_offset_profile(camera, db.distance_mm, views_conditions, params.edges);
    db.query_edge_offset = measure_edge_offset_profile(camera, db.distance_mm, params.query_conditions, params.edges);
  }
  db.turns = find_part_turns(mesh, db.diameter_mm);
  return db;
}

}  // namespace mfcd::vision
