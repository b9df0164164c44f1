#include "vision/pose/pose_refiner.hpp"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace mfcd::vision {

void RefinerParams::validate() const {
  auto fail = [](const std::string& field, const std::string& why) {
    throw std::invalid_argument("pose refiner: " + field + " " + why);
  };
  if (max_iterations < 1) fail("max_iterations", "must be >= 1");
  if (first_view_iterations < 0) fail("first_view_iterations", "must be >= 0");
  if (solver_iterations < 1) fail("solver_iterations", "must be >= 1");
  if (!(lambda_px_per_rad >= 0)) fail("lambda_px_per_rad", "must be >= 0");
  if (!(final_gate_px > 0)) fail("final_gate_px", "must be > 0");
  if (!(initial_gate_px >= final_gate_px)) fail("initial_gate_px", "must be >= final_gate_px");
  if (gate_shrink_iterations < 0) fail("gate_shrink_iterations", "must be >= 0");
  if (!(loss_scale_px > 0)) fail("loss_scale_px", "must be > 0");
  if (!(first_view_max_step_mm >= 0) || !(first_view_max_step_deg >= 0))
    fail("first_view_max_step_mm/first_view_max_step_deg", "must be >= 0");
  if (!(rerender_px >= 0)) fail("rerender_px", "must be >= 0");
  if (!(converged_px >= 0)) fail("converged_px", "must be >= 0");
  if (!(fresh_px >= 0)) fail("fresh_px", "must be >= 0");
  if (min_correspondences < 6) fail("min_correspondences", "must be >= 6 (six pose parameters)");
  if (!(inlier_cost_px > 0)) fail("inlier_cost_px", "must be > 0");
}

namespace {

// One 3-D-to-2-D correspondence of Eq. 22, with the normal of the matched detected edge.
struct Correspondence {
  double X[3];  // R0 * (X_model - centre): the model point rotated by the current estimate
  int view;
  double vx, vy;  // matched edge pixel
  double nx, ny;  // unit normal of the matched edge (tangent rotated by 90 degrees)
};

struct ViewGeometry {
  double R[9], t[3];  // reference -> camera
  double fx, fy, cx, cy;
};

}  // namespace

struct PoseRefiner::Impl {
  struct View {
    RefinementView input;
    ViewGeometry geometry;
    DirectionalEdgeIndex index;
    DepthEdges chain_edges;  // edges with directions from the pixel chains
    std::vector<ModelEdgePoint> points;
    RigidTransform rendered_at;
    bool has_render = false;
  };
  std::vector<View> views;
  std::vector<Correspondence> correspondences;
  std::vector<std::unique_ptr<ceres::CostFunction>> residuals;  // one per correspondence slot
  std::unique_ptr<ceres::LossFunction> loss;
  ceres::Solver::Options solver;

  // Point-to-line reprojection error (px): the projected model point's distance from the
  // matched edge's tangent line, i.e. its offset along the edge normal.
  struct PointToLine {
    const Impl* impl;
    size_t slot;
    template <typename T>
    bool operator()(const T* w, const T* t, T* r) const {
      const Correspondence& c = impl->correspondences[slot];
      const ViewGeometry& g = impl->views[static_cast<size_t>(c.view)].geometry;
      const T X[3] = {T(c.X[0]), T(c.X[1]), T(c.X[2])};
      T p[3];
      ceres::AngleAxisRotatePoint(w, X, p);
      for (int i = 0; i < 3; ++i) p[i] += t[i];
      T q[3];
      for (int i = 0; i < 3; ++i) q[i] = g.R[3 * i] * p[0] + g.R[3 * i + 1] * p[1] + g.R[3 * i + 2] * p[2] + g.t[i];
      const T u = g.fx * q[0] / q[2] + g.cx;
      const T v = g.fy * q[1] / q[2] + g.cy;
      r[0] = c.nx * (u - c.vx) + c.ny * (v - c.vy);
      return true;
    }
  };

  explicit Impl(const RefinerParams& p) {
    if (p.loss == RefinerParams::Loss::cauchy)
      loss = std::make_unique<ceres::CauchyLoss>(p.loss_scale_px);
    else
      loss = std::make_unique<ceres::HuberLoss>(p.loss_scale_px);
    solver.linear_solver_type = ceres::DENSE_QR;
    solver.logging_type = ceres::SILENT;
    solver.minimizer_progress_to_stdout = false;
    solver.num_threads = 1;
  }

  // Mean image displacement (px) of the view's model points between poses a and b (every 4th
  // point: an estimate is enough). Infinite when the view has no points yet.
  static double mean_displacement_px(const View& v, const RigidTransform& a, const RigidTransform& b) {
    if (v.points.empty()) return std::numeric_limits<double>::infinity();
    const RigidTransform ca = v.input.reference_to_camera * a, cb = v.input.reference_to_camera * b;
    double sum = 0;
    int n = 0;
    for (size_t i = 0; i < v.points.size(); i += 4) {
      const cv::Vec3d pa = ca.apply(v.points[i].point_model), pb = cb.apply(v.points[i].point_model);
      if (pa[2] <= 1e-6 || pb[2] <= 1e-6) return std::numeric_limits<double>::infinity();
      sum += cv::norm(v.input.camera.project(pa) - v.input.camera.project(pb));
      ++n;
    }
    return sum / n;
  }

  void ensure_slots(size_t n) {
    if (correspondences.size() < n) correspondences.resize(n);
    while (residuals.size() < n)
      residuals.emplace_back(
          new ceres::AutoDiffCostFunction<PointToLine, 1, 3, 3>(new PointToLine{this, residuals.size()}));
  }
};

PoseRefiner::PoseRefiner(MfcRenderer& renderer, const RefinerParams& params)
    : renderer_(renderer), params_(params), sampler_(renderer, params.model_edges), impl_() {
  sampler_.set_params(params_.model_edges);
  params_.validate();
  impl_ = std::make_unique<Impl>(params_);
  impl_->solver.max_num_iterations = params_.solver_iterations;
}

PoseRefiner::~PoseRefiner() = default;

size_t PoseRefiner::view_count() const { return impl_->views.size(); }

void PoseRefiner::prepare(std::span<const RefinementView> views) {
  if (views.empty()) throw std::invalid_argument("pose refiner: no views given");
  impl_->views.resize(views.size());
  for (size_t k = 0; k < views.size(); ++k) {
    const RefinementView& v = views[k];
    const std::string name = "pose refiner: view " + std::to_string(k);
    if (!v.edges) throw std::invalid_argument(name + ": no edge map (null)");
    if (v.edges->edges.size() != v.camera.image_size)
      throw std::invalid_argument(name + ": edge map is " + std::to_string(v.edges->edges.cols) + "x" +
                                  std::to_string(v.edges->edges.rows) + " but its camera is " +
                                  std::to_string(v.camera.image_size.width) + "x" +
                                  std::to_string(v.camera.image_size.height));
    Impl::View& s = impl_->views[k];
    if (params_.edge_directions_from_chains && !v.edges->edges.empty()) {
      if (v.edges->edges.type() != CV_8UC1) throw std::invalid_argument(name + ": edges must be 8-bit single channel");
      s.chain_edges.edges = v.edges->edges;  // shared, not copied
      edge_tangents(v.edges->edges, s.chain_edges.direction);
      s.index.build(s.chain_edges, name.c_str());
    } else {
      s.index.build(*v.edges, name.c_str());
    }
    if (s.index.edge_count() == 0) throw std::invalid_argument(name + ": the edge map has no edge pixels");
    s.input = v;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) s.geometry.R[3 * i + j] = v.reference_to_camera.R(i, j);
      s.geometry.t[i] = v.reference_to_camera.t[i];
    }
    s.geometry.fx = v.camera.fx();
    s.geometry.fy = v.camera.fy();
    s.geometry.cx = v.camera.cx();
    s.geometry.cy = v.camera.cy();
    s.points.reserve(static_cast<size_t>(params_.model_edges.max_points));
    s.has_render = false;
  }
  impl_->ensure_slots(views.size() * static_cast<size_t>(params_.model_edges.max_points));
}

double PoseRefiner::gate_at(int iteration) const {
  if (iteration >= params_.gate_shrink_iterations || params_.gate_shrink_iterations == 0) return params_.final_gate_px;
  const double f = static_cast<double>(iteration) / params_.gate_shrink_iterations;
  return params_.initial_gate_px * std::pow(params_.final_gate_px / params_.initial_gate_px, f);
}

RefinementResult PoseRefiner::refine(const PoseModel& model, const RigidTransform& initial,
                                     Clock::time_point deadline) {
  Impl& im = *impl_;
  if (im.views.empty()) throw std::logic_error("pose refiner: refine() called before prepare()");
  RefinementResult result;
  RigidTransform pose = initial;
  const cv::Vec3d centre = 0.5 * (model.bbox_min + model.bbox_max);
  for (auto& v : im.views) v.has_render = false;
  bool refresh = false;  // render again at the current pose before the next iteration

  for (int it = 0; it < params_.max_iterations; ++it) {
    if (Clock::now() >= deadline) {
      result.deadline_hit = true;
      break;
    }
    const bool joint = it >= params_.first_view_iterations || im.views.size() == 1;
    const size_t active = joint ? im.views.size() : 1;
    const double gate = gate_at(it);
    size_t n = 0;
    for (size_t k = 0; k < active; ++k) {
      Impl::View& v = im.views[k];
      const RigidTransform m2c = v.input.reference_to_camera * pose;
      if (!v.has_render || refresh || Impl::mean_displacement_px(v, v.rendered_at, pose) > params_.rerender_px) {
        sampler_.sample(model, m2c, v.input.camera, v.points);
        v.rendered_at = pose;
        v.has_render = true;
        ++result.renders;
      }
      for (const ModelEdgePoint& mp : v.points) {
        const cv::Vec3d pc = m2c.apply(mp.point_model);
        if (pc[2] <= 1e-6) continue;
        const EdgeMatch m = v.index.nearest(v.input.camera.project(pc), mp.angle, params_.lambda_px_per_rad, gate);
        if (!m.found) continue;
        Correspondence& c = im.correspondences[n++];
        const cv::Vec3d X = pose.R * (mp.point_model - centre);
        c = {{X[0], X[1], X[2]}, static_cast<int>(k), m.x, m.y, -std::sin(m.angle), std::cos(m.angle)};
      }
    }
    if (n < static_cast<size_t>(params_.min_correspondences)) {
      result.failed = true;
      break;
    }
    // Parameters: rotation w about the model centre (applied after the current rotation) and
    // the centre's position in the reference frame; decoupled, so better conditioned.
    double w[3] = {0, 0, 0};
    const cv::Vec3d tc = pose.R * centre + pose.t;
    double t[3] = {tc[0], tc[1], tc[2]};
    ceres::Problem::Options po;
    po.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(po);
    for (size_t i = 0; i < n; ++i) problem.AddResidualBlock(im.residuals[i].get(), im.loss.get(), w, t);
    ceres::Solver::Summary summary;
    ceres::Solve(im.solver, &problem, &summary);
    // Step limit of the view-0-only phase: scale the update (rotation and centre translation
    // alike) to fit.
    double scale = 1;
    const double step_mm = cv::norm(cv::Vec3d(t[0], t[1], t[2]) - tc), step_rad = cv::norm(cv::Vec3d(w[0], w[1], w[2]));
    const double max_mm = joint ? 0 : params_.first_view_max_step_mm,
                 max_rad = joint ? 0 : radians(params_.first_view_max_step_deg);
    if (max_mm > 0 && step_mm > max_mm) scale = std::min(scale, max_mm / step_mm);
    if (max_rad > 0 && step_rad > max_rad) scale = std::min(scale, max_rad / step_rad);
    for (int i = 0; i < 3; ++i) {
      w[i] *= scale;
      t[i] = tc[i] + scale * (t[i] - tc[i]);
    }
    RigidTransform next;
    next.R = rotation_from_angle_axis({w[0], w[1], w[2]}) * pose.R;
    next.t = cv::Vec3d(t[0], t[1], t[2]) - next.R * centre;
    double moved_px = 0;
    for (size_t k = 0; k < active; ++k)
      if (!im.views[k].points.empty())
        moved_px = std::max(moved_px, Impl::mean_displacement_px(im.views[k], pose, next));
    pose = next;
    result.iterations = it + 1;
    refresh = false;
    if (joint && it + 1 >= params_.first_view_iterations && moved_px < params_.converged_px) {
      bool fresh = true;
      for (const auto& v : im.views)
        fresh = fresh && v.has_render &&
                (v.points.empty() || Impl::mean_displacement_px(v, v.rendered_at, pose) <= params_.fresh_px);
      if (fresh) {
        result.converged = true;
        break;
      }
      refresh = true;
    }
  }
  result.pose = pose;
  evaluate_into(model, result);
  return result;
}

RefinementResult PoseRefiner::evaluate(const PoseModel& model, const RigidTransform& pose) {
  if (impl_->views.empty()) throw std::logic_error("pose refiner: evaluate() called before prepare()");
  for (auto& v : impl_->views) v.has_render = false;
  RefinementResult result;
  result.pose = pose;
  evaluate_into(model, result);
  return result;
}

void PoseRefiner::evaluate_into(const PoseModel& model, RefinementResult& result) {
  const double gate = params_.final_gate_px;
  double sum = 0;
  int count = 0, inliers = 0;
  for (Impl::View& v : impl_->views) {
    const RigidTransform m2c = v.input.reference_to_camera * result.pose;
    // Points rendered near the final pose are reused (reprojected); others are rendered.
    if (!v.has_render || Impl::mean_displacement_px(v, v.rendered_at, result.pose) > params_.fresh_px) {
      sampler_.sample(model, m2c, v.input.camera, v.points);
      v.rendered_at = result.pose;
      v.has_render = true;
      ++result.renders;
    }
    for (const ModelEdgePoint& mp : v.points) {
      const cv::Vec3d pc = m2c.apply(mp.point_model);
      const EdgeMatch m = pc[2] > 1e-6
                              ? v.index.nearest(v.input.camera.project(pc), mp.angle, params_.lambda_px_per_rad, gate)
                              : EdgeMatch{};
      const double cost = m.found ? m.cost : gate;
      sum += cost;
      inliers += cost <= params_.inlier_cost_px;
      ++count;
    }
  }
  result.model_points = count;
  result.mean_cost_px = count ? sum / count : gate;
  result.inlier_fraction = count ? static_cast<double>(inliers) / count : 0.0;
  result.score = std::clamp(result.inlier_fraction * (1.0 - result.mean_cost_px / gate), 0.0, 1.0);
}

}  // namespace mfcd::vision
