#include "vision/dataset/bin_scene.hpp"

#include "vision/common/rotation.hpp"
#include "vision/edges/edge_evaluation.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <utility>

namespace mfcd::vision {

namespace {

void append(Mesh& into, const Mesh& part, const cv::Vec3f& offset) {
  const auto base = static_cast<uint32_t>(into.vertices.size());
  for (const auto& v : part.vertices) into.vertices.push_back(v + offset);
  for (const auto& t : part.triangles) into.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
}

cv::Rect bbox_of(const cv::Mat1b& mask) {
  return cv::countNonZero(mask) ? cv::boundingRect(mask) : cv::Rect(-1, -1, -1, -1);
}

}  // namespace

Mesh make_bin_mesh(const BinGeometry& b) {
  const double ox = b.inner_x_mm + 2 * b.wall_thickness_mm, oy = b.inner_y_mm + 2 * b.wall_thickness_mm;
  Mesh m;
  m.name = "bin";
  append(m, make_box(ox, oy, b.floor_thickness_mm), {0, 0, static_cast<float>(b.floor_thickness_mm / 2)});
  const auto wall_z = static_cast<float>(-b.wall_height_mm / 2);
  const auto wx = static_cast<float>((b.inner_x_mm + b.wall_thickness_mm) / 2);
  const auto wy = static_cast<float>((b.inner_y_mm + b.wall_thickness_mm) / 2);
  for (float s : {-1.f, 1.f}) {
    append(m, make_box(b.wall_thickness_mm, oy, b.wall_height_mm), {s * wx, 0, wall_z});
    append(m, make_box(b.inner_x_mm, b.wall_thickness_mm, b.wall_height_mm), {0, s * wy, wall_z});
  }
  return m;
}

BinSimulator::BinSimulator(const CameraConfig& camera, std::vector<PartModel> models, const BinSceneOptions& options)
    : camera_(camera), models_(std::move(models)), options_(options) {
  if (models_.empty()) throw std::invalid_argument("bin simulator: no part models");
  const BinGeometry& b = options_.bin;
  if (b.inner_x_mm <= 0 || b.inner_y_mm <= 0 || b.wall_height_mm <= 0 || b.wall_thickness_mm <= 0 ||
      b.floor_thickness_mm <= 0)
    throw std::invalid_argument("bin simulator: bin sizes must be positive");
  if (b.wall_height_mm >= camera_.working_distance_mm * 0.6)
    throw std::invalid_argument("bin simulator: walls reach too close to the camera");
  if (options_.parts_per_image < 0 || options_.cell_mm <= 0 || options_.max_occlusion < 0)
    throw std::invalid_argument("bin simulator: parts_per_image, cell_mm and max_occlusion must not be negative");
  if (!(options_.max_lean_deg >= 0 && options_.max_lean_deg < 90))
    throw std::invalid_argument("bin simulator: max_lean_deg must be in [0, 90)");
  if (options_.missing.fraction < 0 || options_.missing.fraction > 0.9 || options_.missing.stretch_px < 2)
    throw std::invalid_argument("bin simulator: missing-edge fraction must be in [0, 0.9], stretch >= 2 px");
  if (options_.clutter.min_rods < 0 || options_.clutter.max_rods < options_.clutter.min_rods ||
      options_.clutter.min_length_mm <= 0 || options_.clutter.max_length_mm < options_.clutter.min_length_mm ||
      options_.clutter.width_mm <= 0)
    throw std::invalid_argument("bin simulator: clutter rods need 0 <= min <= max and positive sizes");
  for (const auto& m : models_) {
    poses_.push_back(stable_resting_poses(m.mesh));
    if (poses_.back().empty())
      throw std::invalid_argument("bin simulator: model '" + m.name + "' has no stable resting face");
    com_.push_back(centre_of_mass(m.mesh));
  }
  bin_ = make_bin_mesh(b);
  // Five rod lengths spread over the range: the renderer keeps one mesh per length.
  for (int k = 0; k < 5; ++k) {
    const double len =
        options_.clutter.min_length_mm + (options_.clutter.max_length_mm - options_.clutter.min_length_mm) * k / 4.0;
    rods_.push_back(make_box(len, options_.clutter.width_mm, options_.clutter.width_mm));
  }
  renderer_ = std::make_unique<MfcRenderer>(camera_, options_.render);
  table_id_ = renderer_->add_mesh(make_plane(2000));
  bin_id_ = renderer_->add_mesh(bin_, 10.0);
  for (const auto& m : models_) model_ids_.push_back(renderer_->add_mesh(m.mesh));
  for (const auto& r : rods_) rod_ids_.push_back(renderer_->add_mesh(r, 10.0));
  extractor_ = std::make_unique<DepthEdgeExtractor>(camera_.camera, camera_.flashes);
}

BinSimulator::~BinSimulator() = default;

std::vector<ScenePart> BinSimulator::scene_parts(const BinLayout& layout) const {
  const double floor_z = camera_.working_distance_mm;
  std::vector<ScenePart> parts;
  parts.push_back(
      {table_id_, cv::Matx33d::eye(), {0, 0, floor_z + options_.bin.floor_thickness_mm}, Material::matte(0.35f)});
  parts.push_back({bin_id_, cv::Matx33d::eye(), {0, 0, floor_z}, Material::matte(0.5f)});
  for (const auto& p : layout.parts)
    parts.push_back({model_ids_[static_cast<size_t>(p.model)], p.R, p.t_mm, p.material});
  for (const auto& c : layout.clutter) parts.push_back({rod_ids_[static_cast<size_t>(c.rod)], c.R, c.t_mm, c.material});
  return parts;
}

bool BinSimulator::occlusion_ok(const BinLayout& layout, std::vector<int>& px_alone) {
  if (options_.max_occlusion >= 1.0) return true;
  const auto parts = scene_parts(layout);
  cv::Mat1f depth;
  cv::Mat1b index;
  // Silhouettes of parts alone do not change as others are added: computed once each.
  while (px_alone.size() < layout.parts.size()) {
    const ScenePart& p = parts[static_cast<size_t>(first_part_index() - 1) + px_alone.size()];
    renderer_->render_depth(std::span(&p, 1), depth, index);
    px_alone.push_back(whole_silhouette(p, index, nullptr));
  }
  renderer_->render_depth(parts, depth, index);
  std::vector<int> visible(parts.size() + 1, 0);
  for (int y = 0; y < index.rows; ++y)
    for (int x = 0; x < index.cols; ++x) ++visible[index(y, x)];
  for (size_t k = 0; k < layout.parts.size(); ++k) {
    const int all = px_alone[k];
    const int vis = visible[k + static_cast<size_t>(first_part_index())];
    if (all == 0 || 1.0 - static_cast<double>(vis) / all > options_.max_occlusion) return false;
  }
  return true;
}

int BinSimulator::whole_silhouette(const ScenePart& part, const cv::Mat1b& in_image, cv::Rect* bbox) {
  const int w = in_image.cols, h = in_image.rows;
  const bool touches = cv::countNonZero(in_image.row(0)) || cv::countNonZero(in_image.row(h - 1)) ||
                       cv::countNonZero(in_image.col(0)) || cv::countNonZero(in_image.col(w - 1));
  // A part's silhouette is connected: one that touches no border lies wholly inside the image.
  const int inside = cv::countNonZero(in_image);
  if (!touches && inside) {
    if (bbox) *bbox = cv::boundingRect(in_image);
    return inside;
  }
  if (!wide_renderer_) {
    CameraConfig wide = camera_;
    wide.camera = camera_.camera.cropped(cv::Rect(-w, -h, 3 * w, 3 * h));
    wide_renderer_ = std::make_unique<MfcRenderer>(wide, options_.render);
    wide_renderer_->add_mesh(make_plane(2000));
    wide_renderer_->add_mesh(bin_, 10.0);
    for (const auto& m : models_) wide_renderer_->add_mesh(m.mesh);
    for (const auto& r : rods_) wide_renderer_->add_mesh(r, 10.0);
  }
  cv::Mat1f depth;
  cv::Mat1b index;
  wide_renderer_->render_depth(std::span(&part, 1), depth, index);
  const int n = cv::countNonZero(index);
  if (bbox) *bbox = n ? cv::boundingRect(index) - cv::Point(w, h) : cv::Rect(-1, -1, -1, -1);
  return n;
}

bool BinSimulator::drop(BinLayout& layout, bool is_part, HeightMap& top, std::vector<int>& px_alone,
                        std::mt19937_64& rng) {
  const BinGeometry& b = options_.bin;
  const double floor_z = camera_.working_distance_mm;
  std::uniform_real_distribution<double> unit(0, 1);
  PlacedObject obj;
  if (is_part) {
    obj.model = static_cast<int>(rng() % models_.size());
    Material& m = obj.material;
    const double u = unit(rng);
    m = u < options_.shiny_fraction ? Material::shiny() : Material::matte(static_cast<float>(0.45 + 0.45 * unit(rng)));
    if (unit(rng) < options_.painted_fraction) {
      m.paint = unit(rng) < 0.5 ? Material::Paint::stripes : Material::Paint::checker;
      m.paint_period_mm = static_cast<float>(4 + 4 * unit(rng));
      m.paint_albedo = static_cast<float>(0.08 + 0.12 * unit(rng));
    }
  } else {
    obj.rod = static_cast<int>(rng() % rods_.size());
    obj.material = Material::matte(static_cast<float>(0.3 + 0.6 * unit(rng)));
  }
  const Mesh& mesh = is_part ? models_[static_cast<size_t>(obj.model)].mesh : rods_[static_cast<size_t>(obj.rod)];
  const cv::Vec3d com = is_part ? com_[static_cast<size_t>(obj.model)] : cv::Vec3d(0, 0, 0);
  const auto& poses = is_part ? poses_[static_cast<size_t>(obj.model)] : std::vector<RestingPose>{};
  // Faces are chosen with probability proportional to their support area or solid angle.
  std::vector<double> weights;
  for (const auto& p : poses)
    weights.push_back(options_.resting_weight == BinSceneOptions::RestingWeight::solid_angle ? p.solid_angle_sr
                                                                                             : p.support_area_mm2);
  std::discrete_distribution<size_t> pick_face(weights.begin(), weights.end());
  const cv::Mat1f& top_h = top.heights();

  for (int attempt = 0; attempt < options_.attempts_per_object; ++attempt) {
    const cv::Matx33d rest = poses.empty() ? cv::Matx33d::eye() : poses[pick_face(rng)].R;
    cv::Matx33d R = rotation_about_z(2 * std::numbers::pi * unit(rng)) * rest;
    if (is_part && options_.max_lean_deg > 0) {
      // Tilted about the horizontal axis at `azimuth`: turn that axis onto x, tilt about x, turn back.
      const double azimuth = 2 * std::numbers::pi * unit(rng);
      const double lean = options_.max_lean_deg * std::numbers::pi / 180 * unit(rng);
      const double c = std::cos(lean), s = std::sin(lean);
      const cv::Matx33d about_x(1, 0, 0, 0, c, -s, 0, s, c);
      R = rotation_about_z(azimuth) * about_x * rotation_about_z(-azimuth) * R;
    }
    cv::Vec3d lo(1e300, 1e300, 1e300), hi(-1e300, -1e300, -1e300);
    for (const auto& v : mesh.vertices) {
      const cv::Vec3d p = R * cv::Vec3d(v);
      for (int k = 0; k < 3; ++k) {
        lo[k] = std::min(lo[k], p[k]);
        hi[k] = std::max(hi[k], p[k]);
      }
    }
    // Random x/y with the rotated part inside the inner walls (half a cell of play).
    const double m = options_.cell_mm;
    const double x_min = -b.inner_x_mm / 2 + m - lo[0], x_max = b.inner_x_mm / 2 - m - hi[0];
    const double y_min = -b.inner_y_mm / 2 + m - lo[1], y_max = b.inner_y_mm / 2 - m - hi[1];
    if (x_min > x_max || y_min > y_max) {
      ++layout.rejected_placements;
      continue;
    }
    // Start with the lowest point on the floor (height 0) ...
    cv::Vec3d t(x_min + (x_max - x_min) * unit(rng), y_min + (y_max - y_min) * unit(rng), floor_z - hi[2]);
    HeightMap bottom(-b.inner_x_mm / 2, -b.inner_y_mm / 2, top_h.cols, top_h.rows, top.cell_mm(), floor_z,
                     std::numeric_limits<float>::infinity());
    bottom.lower_to_bottom(mesh, R, t);
    // ... then lift it until its lower surface clears everything below in every cell.
    float lift = 0;
    const cv::Mat1f& bh = bottom.heights();
    for (int r = 0; r < bh.rows; ++r)
      for (int c = 0; c < bh.cols; ++c)
        if (std::isfinite(bh(r, c))) lift = std::max(lift, top_h(r, c) - bh(r, c));
    if (lift > 0) lift += static_cast<float>(options_.clearance_mm);
    t[2] -= lift;
    const double top_height = floor_z - (t[2] + lo[2]);
    if (top_height > b.wall_height_mm) {  // would stick out of the bin
      ++layout.rejected_placements;
      continue;
    }
    // It rests where its lower surface (nearly) touches the surface below; the centre of
    // mass must lie above the convex hull of those contacts or it would tip over.
    std::vector<cv::Point2f> contacts;
    for (int r = 0; r < bh.rows; ++r)
      for (int c = 0; c < bh.cols; ++c)
        if (std::isfinite(bh(r, c)) && bh(r, c) + lift - top_h(r, c) <= options_.contact_tolerance_mm) {
          const cv::Point2d p = top.cell_centre(c, r);
          contacts.emplace_back(static_cast<float>(p.x), static_cast<float>(p.y));
        }
    bool stable = contacts.size() >= 3;
    if (stable) {
      std::vector<cv::Point2f> hull;
      cv::convexHull(contacts, hull);
      const cv::Vec3d g = R * com + t;
      stable = cv::contourArea(hull) > 1.0 &&
               cv::pointPolygonTest(hull, cv::Point2f(static_cast<float>(g[0]), static_cast<float>(g[1])), true) >=
                   -options_.cell_mm / 2;
    }
    if (!stable) {
      ++layout.rejected_placements;
      continue;
    }
    obj.R = R;
    obj.t_mm = t;
    (is_part ? layout.parts : layout.clutter).push_back(obj);
    if (!occlusion_ok(layout, px_alone)) {
      (is_part ? layout.parts : layout.clutter).pop_back();
      if (is_part) px_alone.resize(std::min(px_alone.size(), layout.parts.size()));
      ++layout.rejected_placements;
      continue;
    }
    top.raise_to_top(mesh, R, t);
    return true;
  }
  return false;
}

BinLayout BinSimulator::layout(uint64_t seed) {
  std::mt19937_64 rng(seed);
  const BinGeometry& b = options_.bin;
  const int cols = static_cast<int>(std::ceil(b.inner_x_mm / options_.cell_mm));
  const int rows = static_cast<int>(std::ceil(b.inner_y_mm / options_.cell_mm));
  HeightMap top(-b.inner_x_mm / 2, -b.inner_y_mm / 2, cols, rows, options_.cell_mm, camera_.working_distance_mm, 0.f);
  BinLayout layout;
  std::vector<int> px_alone;
  for (int k = 0; k < options_.parts_per_image; ++k) drop(layout, true, top, px_alone, rng);
  if (options_.clutter.enabled) {
    const int rods =
        options_.clutter.min_rods +
        static_cast<int>(rng() % static_cast<uint64_t>(options_.clutter.max_rods - options_.clutter.min_rods + 1));
    for (int k = 0; k < rods; ++k) drop(layout, false, top, px_alone, rng);
  }
  return layout;
}

SimulatedImage BinSimulator::simulate(uint64_t seed) { return simulate(layout(seed), seed); }

SimulatedImage BinSimulator::simulate(BinLayout layout, uint64_t seed) {
  SimulatedImage im;
  im.layout = std::move(layout);
  const auto parts = scene_parts(im.layout);
  MfcRender render;
  renderer_->render(parts, render, seed);
  im.frames = std::move(render.frames);
  im.depth_mm = render.depth_mm;
  cv::Mat1f depth;
  cv::Mat1b index;
  for (size_t k = 0; k < im.layout.parts.size(); ++k) {
    const PlacedObject& p = im.layout.parts[k];
    PartInstance inst;
    inst.model = p.model;
    inst.obj_id = models_[static_cast<size_t>(p.model)].obj_id;
    inst.R = p.R;
    inst.t_mm = p.t_mm;
    const ScenePart& sp = parts[static_cast<size_t>(first_part_index() - 1) + k];
    renderer_->render_depth(std::span(&sp, 1), depth, index);
    inst.mask_all = index > 0;
    inst.mask_visib = render.part_index == static_cast<int>(k) + first_part_index();
    inst.px_count_all = whole_silhouette(sp, index, &inst.bbox_obj);
    // The simulated depth is valid wherever the table or bin is seen, i.e. everywhere.
    inst.px_count_valid = cv::countNonZero(inst.mask_all & (im.depth_mm > 0));
    inst.px_count_visib = cv::countNonZero(inst.mask_visib);
    inst.visib_fract = inst.px_count_all ? static_cast<double>(inst.px_count_visib) / inst.px_count_all : 0;
    inst.bbox_visib = bbox_of(inst.mask_visib);
    im.instances.push_back(std::move(inst));
  }
  corrupt(im, seed);
  return im;
}

void BinSimulator::corrupt(SimulatedImage& im, uint64_t seed) {
  CorruptionReport& rep = im.corruption;
  rep.clutter_rods = static_cast<int>(im.layout.clutter.size());
  const cv::Mat1b truth = depth_discontinuities(im.depth_mm, options_.edge_min_jump_mm);
  DepthEdges edges;
  extractor_->extract(im.frames, edges);
  const EdgeScore clean = score_edges(edges.edges, truth, options_.edge_tolerance_px);
  rep.true_edge_px = clean.truth;
  rep.recall_clean = clean.recall;
  rep.recall_corrupted = clean.recall;
  if (!options_.missing.enabled || options_.missing.fraction <= 0 || clean.recall <= 0) return;

  // True edge pixels the extractor finds in the clean images: the ones that can be removed.
  const auto tol = static_cast<float>(options_.edge_tolerance_px + 1e-6);
  cv::Mat1f to_detected;
  cv::distanceTransform(255 - edges.edges, to_detected, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  const cv::Mat1b found = truth & (to_detected <= tol);
  const int clean_px = cv::countNonZero(edges.edges);
  const auto added_fraction = [&](const cv::Mat1b& now) {
    return clean_px ? cv::countNonZero(now & (to_detected > tol)) / static_cast<double>(clean_px) : 0.0;
  };
  std::vector<cv::Point> candidates;
  cv::findNonZero(found, candidates);
  std::mt19937_64 rng(seed ^ 0x9e3779b97f4a7c15ULL);
  std::shuffle(candidates.begin(), candidates.end(), rng);

  const double want = options_.missing.fraction;
  const auto radius = static_cast<int>(std::lround(options_.missing.stretch_px / 2));
  cv::Mat1b stretches(truth.size(), 0);
  // A stretch lifts every flash to the brightest one over a disc on the edge. A cast shadow
  // wider than the disc would keep its lit-to-shadow step, only moved to the disc's rim, and
  // the removal would draw a wavy false edge there instead of removing one (a 40 mm step casts
  // shadows of 10-25 px here). So each flash's stretch also covers that flash's own shadow
  // beyond the disc: the disc swept along the flash's shadow direction to where the shadow
  // ends. The sweep's sides run along that direction, so they make no step for that flash.
  const MfcFrames clean_frames = im.frames;
  const size_t n_flash = clean_frames.flash.size();
  std::vector<cv::Mat1f> clean_ratio(n_flash);
  for (size_t i = 0; i < n_flash; ++i) clean_ratio[i] = extractor_->ratio(i).clone();
  std::vector<FlashEpipole> epipoles;
  for (const auto& led : camera_.flashes.positions_mm) epipoles.push_back(flash_epipole(camera_.camera, led));
  std::vector<cv::Mat1b> shadow_sweeps(n_flash);
  for (auto& m : shadow_sweeps) m = cv::Mat1b(truth.size(), 0);
  const auto sweep_shadows = [&](cv::Point p) {
    constexpr float kShadowRatio = 0.6f;  // below this share of the brightest flash: in shadow
    constexpr int kMaxShadowPx = 60;
    for (size_t i = 0; i < n_flash; ++i) {
      cv::Vec2d d = epipoles[i].shadow_direction(p.x, p.y);
      const double len = std::hypot(d[0], d[1]);
      if (len <= 0) continue;
      d /= len;
      const auto along = [&](int t) {
        return cv::Point(static_cast<int>(std::lround(p.x + t * d[0])), static_cast<int>(std::lround(p.y + t * d[1])));
      };
      int last = 0;
      for (int t = 1; t <= kMaxShadowPx; ++t) {
        const cv::Point q = along(t);
        if (q.x < 0 || q.y < 0 || q.x >= truth.cols || q.y >= truth.rows) break;
        if (clean_ratio[i](q) < kShadowRatio)
          last = t;
        else if (last > 0 || t > radius + 2)
          break;
      }
      if (last > radius) cv::line(shadow_sweeps[i], p, along(last), 255, 2 * radius + 1);
    }
  };
  size_t next = 0;
  int covered = 0;  // found pixels inside the stretches
  // Blurring the blend weights keeps the ratio images smooth where an equalised stretch
  // begins, so the stretch's own border does not become an edge. The blur also removes a
  // little beyond the disc, and a flash's shadow sweep may cross other edges (together about
  // 1.5-2 times what the discs cover), so the first goal aims low and the loop tops up by what
  // a covered pixel has removed so far.
  const auto n_candidates = static_cast<double>(candidates.size());
  double goal = 0.4 * want * n_candidates;
  for (int round = 0; round < 8; ++round) {
    while (next < candidates.size() && covered < goal) {
      const cv::Point p = candidates[next++];
      if (stretches(p)) continue;
      const cv::Rect roi =
          cv::Rect(p.x - radius, p.y - radius, 2 * radius + 1, 2 * radius + 1) & cv::Rect(0, 0, truth.cols, truth.rows);
      const int before = cv::countNonZero(found(roi) & stretches(roi));
      cv::circle(stretches, p, radius, 255, cv::FILLED);
      sweep_shadows(p);
      covered += cv::countNonZero(found(roi) & stretches(roi)) - before;
      ++rep.stretches;
    }
    std::vector<cv::Mat1f> w(n_flash);
    for (size_t i = 0; i < n_flash; ++i) {
      cv::Mat1b grown;
      cv::dilate(stretches | shadow_sweeps[i], grown, cv::getStructuringElement(cv::MORPH_ELLIPSE, {7, 7}));
      grown.convertTo(w[i], CV_32F, 1.0 / 255);
      cv::GaussianBlur(w[i], w[i], {0, 0}, 2.5);
    }
    for (int y = 0; y < truth.rows; ++y)
      for (int x = 0; x < truth.cols; ++x) {
        uchar mx = 0;
        for (const auto& f : clean_frames.flash) mx = std::max(mx, f(y, x));
        for (size_t i = 0; i < n_flash; ++i) {
          const float a = std::min(1.f, 1.5f * w[i](y, x));
          im.frames.flash[i](y, x) = cv::saturate_cast<uchar>((1 - a) * clean_frames.flash[i](y, x) + a * mx);
        }
      }
    extractor_->extract(im.frames, edges);
    const EdgeScore now = score_edges(edges.edges, truth, options_.edge_tolerance_px);
    rep.recall_corrupted = now.recall;
    rep.removed_fraction = 1.0 - now.recall / clean.recall;
    rep.added_fraction = added_fraction(edges.edges);
    if (rep.removed_fraction >= want - 0.005 || next >= candidates.size()) break;
    const double removed_per_covered = covered > 0 ? rep.removed_fraction * n_candidates / covered : 1.0;
    // A new stretch removes more than the average so far (its sweeps join earlier ones): top up
    // by part of the gap and measure again rather than overshoot.
    goal += 0.6 * (want - rep.removed_fraction) / std::max(removed_per_covered, 0.5) * n_candidates;
  }
}

}  // namespace mfcd::vision
