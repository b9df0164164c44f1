// Rendering checked against analytic ray casting of the same shapes: depth within 0.1 mm,
// silhouettes within 1 px, LED shadows where the light ray is blocked.
#include "vision/render/mfc_renderer.hpp"
#include "vision/render/shadow_footprint.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <functional>
#include <optional>

#include "tests/hal/alloc_counter.hpp"

using namespace mfcd::vision;

namespace {

CameraConfig sim_config() { return load_camera_config(MFC_SOURCE_DIR "/config/camera-sim.yaml"); }

cv::Matx33d rotation(double rx, double ry, double rz) {
  // Rodrigues' formula (calib3d is not a dependency of this area).
  const cv::Vec3d w(rx, ry, rz);
  const double th = cv::norm(w);
  if (th < 1e-15) return cv::Matx33d::eye();
  const cv::Vec3d k = w / th;
  const cv::Matx33d Kx(0, -k[2], k[1], k[2], 0, -k[0], -k[1], k[0], 0);
  return cv::Matx33d::eye() + std::sin(th) * Kx + (1 - std::cos(th)) * Kx * Kx;
}

// Ray o + s d (object frame) against an analytic shape: smallest s > 0, if any.
using Shape = std::function<std::optional<double>(const cv::Vec3d& o, const cv::Vec3d& d)>;

Shape box_shape(cv::Vec3d half) {
  return [half](const cv::Vec3d& o, const cv::Vec3d& d) -> std::optional<double> {
    double lo = -1e300, hi = 1e300;
    for (int k = 0; k < 3; ++k) {
      if (std::abs(d[k]) < 1e-15) {
        if (std::abs(o[k]) > half[k]) return std::nullopt;
        continue;
      }
      double a = (-half[k] - o[k]) / d[k], b = (half[k] - o[k]) / d[k];
      if (a > b) std::swap(a, b);
      lo = std::max(lo, a);
      hi = std::min(hi, b);
    }
    if (lo > hi || hi <= 1e-9) return std::nullopt;
    return lo > 1e-9 ? lo : hi;
  };
}

Shape sphere_shape(double r) {
  return [r](const cv::Vec3d& o, const cv::Vec3d& d) -> std::optional<double> {
    const double a = d.dot(d), b = 2 * o.dot(d), c = o.dot(o) - r * r;
    const double disc = b * b - 4 * a * c;
    if (disc < 0) return std::nullopt;
    const double s = (-b - std::sqrt(disc)) / (2 * a);
    return s > 0 ? std::optional<double>(s) : std::nullopt;
  };
}

Shape cylinder_shape(double r, double h) {  // axis z, from -h/2 to h/2
  return [r, h](const cv::Vec3d& o, const cv::Vec3d& d) -> std::optional<double> {
    std::optional<double> best;
    auto take = [&](double s) {
      if (s > 1e-9 && (!best || s < *best)) best = s;
    };
    const double a = d[0] * d[0] + d[1] * d[1], b = 2 * (o[0] * d[0] + o[1] * d[1]),
                 c = o[0] * o[0] + o[1] * o[1] - r * r;
    const double disc = b * b - 4 * a * c;
    if (a > 1e-15 && disc >= 0)
      for (double s : {(-b - std::sqrt(disc)) / (2 * a), (-b + std::sqrt(disc)) / (2 * a)})
        if (std::abs(o[2] + s * d[2]) <= h / 2) take(s);
    if (std::abs(d[2]) > 1e-15)
      for (double zc : {-h / 2, h / 2}) {
        const double s = (zc - o[2]) / d[2];
        const double x = o[0] + s * d[0], y = o[1] + s * d[1];
        if (x * x + y * y <= r * r) take(s);
      }
    return best;
  };
}

// Depth (camera z) of the analytic shape at each pixel centre, 0 where the ray misses.
cv::Mat1f analytic_depth(const PinholeCamera& cam, const Shape& shape, const cv::Matx33d& R, const cv::Vec3d& t) {
  cv::Mat1f depth(cam.image_size, 0.f);
  const cv::Matx33d Kinv = cam.K.inv();
  const cv::Vec3d o = R.t() * (-t);
  for (int v = 0; v < depth.rows; ++v)
    for (int u = 0; u < depth.cols; ++u) {
      const cv::Vec3d ray = Kinv * cv::Vec3d(u, v, 1);  // z component 1: s is the depth
      if (auto s = shape(o, R.t() * ray)) depth(v, u) = static_cast<float>(*s);
    }
  return depth;
}

struct Comparison {
  double max_depth_error_mm = 0;
  int compared = 0;
  int silhouette_mismatches_beyond_1px = 0;
  int silhouette_mismatches = 0;
};

// Depth is compared away from silhouettes (where a pixel centre may fall either side
// of the tessellated outline); every coverage mismatch must have the analytic outline
// within 1 px (a 3x3 neighbourhood holding both hit and miss).
Comparison compare(const cv::Mat1f& rendered, const cv::Mat1f& analytic, double max_slope = 3.0) {
  Comparison c;
  for (int v = 1; v + 1 < rendered.rows; ++v)
    for (int u = 1; u + 1 < rendered.cols; ++u) {
      const bool hr = rendered(v, u) > 0, ha = analytic(v, u) > 0;
      bool any_hit = false, any_miss = false;
      double slope = 0;
      for (int dv = -1; dv <= 1; ++dv)
        for (int du = -1; du <= 1; ++du) {
          const float a = analytic(v + dv, u + du);
          (a > 0 ? any_hit : any_miss) = true;
          if (a > 0 && ha) slope = std::max(slope, std::abs(double(a) - analytic(v, u)));
        }
      if (hr != ha) {
        ++c.silhouette_mismatches;
        if (!(any_hit && any_miss)) ++c.silhouette_mismatches_beyond_1px;
        continue;
      }
      // Grazing surfaces (depth changing by more than max_slope mm per pixel) are
      // dominated by the tessellation, not the renderer.
      if (hr && !any_miss && slope < max_slope) {
        c.max_depth_error_mm = std::max(c.max_depth_error_mm, std::abs(double(rendered(v, u)) - analytic(v, u)));
        ++c.compared;
      }
    }
  return c;
}

struct ShapeCase {
  const char* name;
  Mesh mesh;
  Shape shape;
};

std::vector<ShapeCase> shape_cases() {
  return {{"box", make_box(40, 30, 20), box_shape({20, 15, 10})},
          {"sphere", make_uv_sphere(25, 512, 256), sphere_shape(25)},
          {"cylinder", make_cylinder(20, 40, 512), cylinder_shape(20, 40)}};
}

}  // namespace

TEST(MfcRenderer, UsesAnOpenGlRenderer) {
  MfcRenderer r(sim_config());
  EXPECT_FALSE(r.gl_renderer().empty());
  std::printf("GL renderer: %s\n", r.gl_renderer().c_str());
}

TEST(MfcRenderer, DepthAndSilhouetteMatchAnalyticShapes) {
  MfcRenderer r(sim_config());
  const std::vector<std::pair<cv::Matx33d, cv::Vec3d>> poses = {
      {cv::Matx33d::eye(), {0, 0, 300}},
      {rotation(0.4, -0.3, 0.2), {25, -10, 280}},
      {rotation(-1.1, 0.5, 2.0), {-40, 30, 330}},
  };
  for (const auto& sc : shape_cases()) {
    const int id = r.add_mesh(sc.mesh);
    for (const auto& [R, t] : poses) {
      const ScenePart part{id, R, t, Material::matte()};
      cv::Mat1f depth;
      cv::Mat1b index;
      r.render_depth(std::span(&part, 1), depth, index);
      const cv::Mat1f truth = analytic_depth(r.camera(), sc.shape, R, t);
      const Comparison c = compare(depth, truth);
      EXPECT_GT(c.compared, 5000) << sc.name;
      EXPECT_LT(c.max_depth_error_mm, 0.1) << sc.name << " t=" << t;
      EXPECT_EQ(c.silhouette_mismatches_beyond_1px, 0) << sc.name << " t=" << t;
      for (int v = 0; v < depth.rows; ++v)
        for (int u = 0; u < depth.cols; ++u) ASSERT_EQ(index(v, u) == 1, depth(v, u) > 0);
    }
  }
}

// The full MFC render fills the same depth as the depth-only pass.
TEST(MfcRenderer, FullRenderDepthEqualsDepthPass) {
  MfcRenderer r(sim_config());
  const ScenePart part{r.add_mesh(make_cylinder(20, 40, 64)), rotation(0.3, 0.2, 0), {5, 5, 300}, Material::shiny()};
  MfcRender out;
  r.render(std::span(&part, 1), out);
  cv::Mat1f depth;
  cv::Mat1b index;
  r.render_depth(std::span(&part, 1), depth, index);
  EXPECT_EQ(cv::norm(out.depth_mm, depth, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(out.part_index, index, cv::NORM_INF), 0.0);
  ASSERT_EQ(out.frames.flash.size(), 8u);
}

// A box standing on a plane: a plane point is in LED i's shadow exactly when the segment
// from it to the LED passes through the box.
TEST(MfcRenderer, CastShadowsMatchAnalyticLightRays) {
  const CameraConfig cfg = sim_config();
  RenderOptions opt;
  opt.noise.enabled = false;
  MfcRenderer r(cfg, opt);
  const double floor_z = 330;
  const cv::Vec3d box_t(-10, 5, 315);  // 30 mm tall box on the floor
  const cv::Matx33d box_R = rotation(0, 0, 0.5);
  const std::vector<ScenePart> parts = {
      {r.add_mesh(make_plane(800)), cv::Matx33d::eye(), {0, 0, floor_z}, Material::matte(0.6f)},
      {r.add_mesh(make_box(40, 30, 30)), box_R, box_t, Material::matte(0.8f)}};
  MfcRender out;
  r.render(parts, out);
  const Shape box = box_shape({20, 15, 15});
  const cv::Matx33d Kinv = r.camera().K.inv();
  for (int i = 0; i < 8; ++i) {
    const cv::Vec3d L = cfg.flashes.positions_mm[static_cast<size_t>(i)];
    cv::Mat1b truth(out.depth_mm.size(), 0), seen(out.depth_mm.size(), 0), floor(out.depth_mm.size(), 0);
    for (int v = 0; v < truth.rows; ++v)
      for (int u = 0; u < truth.cols; ++u) {
        if (out.part_index(v, u) != 1) continue;
        floor(v, u) = 255;
        const cv::Vec3d P = Kinv * cv::Vec3d(u, v, 1) * floor_z;
        const auto s = box(box_R.t() * (P - box_t), box_R.t() * (L - P));
        truth(v, u) = (s && *s < 1.0) ? 255 : 0;
        // Shadowed: the flash adds (almost) nothing to the ambient light.
        const float flash = out.flash_linear[static_cast<size_t>(i)](v, u) - out.ambient_linear(v, u);
        seen(v, u) = flash < 5.0f ? 255 : 0;
      }
    cv::Mat1b diff = truth != seen, truth_edge, band;
    cv::morphologyEx(truth, truth_edge, cv::MORPH_GRADIENT, cv::Mat());
    cv::dilate(truth_edge, band, cv::Mat(), {-1, -1}, 1);
    diff.setTo(0, band);
    EXPECT_GT(cv::countNonZero(truth), 500) << "LED " << i;
    EXPECT_EQ(cv::countNonZero(diff), 0) << "LED " << i << ": shadow pixels more than 1 px off the analytic shadow";
  }
}

TEST(MfcRenderer, ABackgroundLeftOutOfTheShadowMapsChangesNoPixel) {
  RenderOptions opt;
  opt.noise.enabled = false;
  MfcRenderer r(sim_config(), opt);
  std::vector<ScenePart> parts = {
      {r.add_mesh(make_plane(800)), cv::Matx33d::eye(), {0, 0, 330}, Material::matte(0.6f)},
      {r.add_mesh(make_box(40, 30, 30)), rotation(0.4, -0.3, 0.5), {-10, 5, 310}, Material::matte(0.8f)}};
  MfcRender casting, not_casting;
  r.render(parts, casting);
  parts[0].casts_shadows = false;
  r.render(parts, not_casting);
  int shadowed = 0;
  for (size_t i = 0; i < 8; ++i) {
    EXPECT_EQ(cv::norm(casting.flash_linear[i], not_casting.flash_linear[i], cv::NORM_INF), 0.0) << "LED " << i;
    shadowed += cv::countNonZero((casting.flash_linear[i] - casting.ambient_linear < 5.0f) & (casting.part_index == 1));
  }
  EXPECT_GT(shadowed, 1000);  // the box's shadows on the plane are there in both
  EXPECT_EQ(cv::norm(casting.depth_mm, not_casting.depth_mm, cv::NORM_INF), 0.0);
  // A part that does cast shadows and is left out loses them: the flag is honoured.
  parts[0].casts_shadows = true;
  parts[1].casts_shadows = false;
  r.render(parts, not_casting);
  EXPECT_GT(cv::norm(casting.flash_linear[0], not_casting.flash_linear[0], cv::NORM_INF), 50.0);
}

// Filling only the texels a window can read gives every pixel the value a whole fill gives,
// bit for bit: in small and large windows, at the frame's corner, with a caster outside the
// window whose shadow falls into it, and after a full-frame render of another scene left other texels behind.
TEST(MfcRenderer, WindowShadowFillEqualsWholeFill) {
  RenderOptions clipped_opt, whole_opt;
  clipped_opt.noise.enabled = whole_opt.noise.enabled = false;
  whole_opt.fill_whole_shadow_maps = true;
  MfcRenderer clipped(sim_config(), clipped_opt), whole(sim_config(), whole_opt);
  auto scene = [](MfcRenderer& r) {
    return std::vector<ScenePart>{
        {r.add_mesh(make_plane(800)), cv::Matx33d::eye(), {0, 0, 330}, Material::matte(0.6f), false},
        {r.add_mesh(make_box(40, 30, 30)), rotation(0.4, -0.3, 0.5), {-10, 5, 310}, Material::matte(0.8f)},
        {r.add_mesh(make_cylinder(6, 60, 48)), rotation(0.2, 0.1, 0), {45, -20, 290}, Material::shiny()}};
  };
  const auto a = scene(clipped), b = scene(whole);
  // Another scene: a plane that casts shadows in front of everything fills every texel with a
  // depth nearer than any of the scene's, so a window pixel that read a texel left behind would
  // be in shadow where the whole fill lights it.
  std::vector<ScenePart> other = a;
  other[0].t_mm = {0, 0, 200};
  other[0].casts_shadows = true;
  other[1].t_mm = {30, -25, 250};
  other[1].R = rotation(-0.6, 0.2, 1.1);
  other[2].t_mm = {-40, 30, 240};
  MfcRender out_a, out_b;
  const cv::Rect windows[] = {{250, 190, 60, 50}, {300, 200, 40, 40}, {0, 0, 90, 70}, {150, 100, 340, 280}};
  int windows_with_shadows = 0;
  for (const cv::Rect& win : windows) {
    clipped.set_camera(clipped.config().camera);
    clipped.render(other, out_a);  // a full frame of the other scene before every window
    clipped.set_camera(clipped.config().camera.cropped(win));
    whole.set_camera(whole.config().camera.cropped(win));
    clipped.render(a, out_a);
    whole.render(b, out_b);
    int shadowed = 0;
    for (size_t i = 0; i < 8; ++i) {
      EXPECT_EQ(cv::norm(out_a.flash_linear[i], out_b.flash_linear[i], cv::NORM_INF), 0.0) << win << " LED " << i;
      shadowed += cv::countNonZero(out_b.flash_linear[i] - out_b.ambient_linear < 5.0f);
    }
    windows_with_shadows += shadowed > 0;
  }
  EXPECT_EQ(windows_with_shadows, 3);  // all but the corner's
}

TEST(ShadowFootprint, HoldsEveryLookupOfTheWindowAndIsSmallerThanTheMap) {
  // An LED 30 mm off axis, a map of 1024 texels over a 60 degree field from 120 mm on.
  const int S = 1024;
  const double fs = (S / 2.0) / (std::tan(30.0 * CV_PI / 180) + 30.0 / 120.0);
  const cv::Vec3d L(30, 0, 0);
  const cv::Matx44d unit_from_led(fs / S, 0, (S / 2.0) / S, 0, 0, fs / S, (S / 2.0) / S, 0, 0, 0, 0.5, 0.5, 0, 0, 1, 0);
  const cv::Matx44d led_from_camera(1, 0, 0, -L[0], 0, 1, 0, -L[1], 0, 0, 1, -L[2], 0, 0, 0, 1);
  const PinholeCamera full = sim_config().camera;
  const PinholeCamera cam = full.cropped({280, 200, 80, 60});
  const ShadowFootprintQuery q{.unit_from_camera = unit_from_led * led_from_camera,
                               .map_size = S,
                               .z_near_mm = 280,
                               .z_far_mm = 340,
                               .led_mm = L,
                               .offset_per_mm = 1.5 / S};
  const cv::Rect box = shadow_footprint(q, cam);
  EXPECT_LT(box.area(), S * S / 16);
  // Sampled points of the window's frustum in that range, moved by the largest offset, and
  // the 2x2 texels linear filtering reads around them, all fall in the box.
  const cv::Matx33d Kinv = cam.K.inv();
  const double offset = 1.5 / S * (340 * 1.2 + 30);
  int checked = 0;
  for (double u = -0.5; u <= cam.image_size.width - 0.5; u += 8)
    for (double v = -0.5; v <= cam.image_size.height - 0.5; v += 6)
      for (double z : {280.0, 310.0, 340.0})
        for (double e : {-offset, offset}) {
          const cv::Vec3d P = Kinv * cv::Vec3d(u, v, 1) * z + cv::Vec3d(e, -e, e);
          const cv::Vec4d s = q.unit_from_camera * cv::Vec4d(P[0], P[1], P[2], 1);
          const double x = s[0] / s[3] * S - 0.5, y = s[1] / s[3] * S - 0.5;
          for (double tx : {std::floor(x), std::floor(x) + 1})
            for (double ty : {std::floor(y), std::floor(y) + 1})
              EXPECT_TRUE(box.contains(cv::Point(static_cast<int>(tx), static_cast<int>(ty))))
                  << "texel " << tx << "," << ty << " outside " << box;
          ++checked;
        }
  EXPECT_GT(checked, 100);
  // A depth range reaching behind the LED, or none, fills the whole map.
  ShadowFootprintQuery behind = q;
  behind.z_near_mm = -10;
  EXPECT_EQ(shadow_footprint(behind, cam), cv::Rect(0, 0, S, S));
  ShadowFootprintQuery empty = q;
  empty.z_far_mm = 100;
  EXPECT_EQ(shadow_footprint(empty, cam), cv::Rect(0, 0, S, S));
}

// Parts of every material (matte, shiny, painted) overlapping in front of a plane, with thin
// triangles (a finely tessellated cylinder) and back faces behind front ones.
std::vector<ScenePart> mixed_scene(MfcRenderer& r) {
  Material painted = Material::matte(0.8f);
  painted.paint = Material::Paint::checker;
  return {{r.add_mesh(make_box(40, 30, 30)), rotation(0.4, -0.3, 0.5), {-10, 5, 310}, painted},
          {r.add_mesh(make_cylinder(6, 60, 96)), rotation(0.2, 0.1, 0), {5, -10, 290}, Material::shiny()},
          {r.add_mesh(make_uv_sphere(12)), cv::Matx33d::eye(), {30, 20, 300}, Material::matte(0.5f)},
          {r.add_mesh(make_plane(800)), cv::Matx33d::eye(), {0, 0, 330}, Material::matte(0.6f), false}};
}

// Deferred shading lights each pixel once from the nearest surface: the values forward
// shading gives every fragment, the nearest kept.
TEST(MfcRenderer, DeferredShadingEqualsForward) {
  RenderOptions deferred_opt, forward_opt;
  deferred_opt.noise.enabled = forward_opt.noise.enabled = false;
  deferred_opt.deferred_shading = true;
  MfcRenderer deferred(sim_config(), deferred_opt), forward(sim_config(), forward_opt);
  const auto a = mixed_scene(deferred), b = mixed_scene(forward);
  MfcRender out_a, out_b;
  deferred.render(a, out_a);
  forward.render(b, out_b);
  EXPECT_EQ(cv::norm(out_a.part_index, out_b.part_index, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(out_a.depth_mm, out_b.depth_mm, cv::NORM_INF), 0.0);
  EXPECT_LE(cv::norm(out_a.ambient_linear, out_b.ambient_linear, cv::NORM_INF), 1e-4);
  double flash_sum = 0;
  for (size_t i = 0; i < 8; ++i) {
    EXPECT_LE(cv::norm(out_a.flash_linear[i], out_b.flash_linear[i], cv::NORM_INF), 1e-4) << "LED " << i;
    EXPECT_EQ(cv::norm(out_a.frames.flash[i], out_b.frames.flash[i], cv::NORM_INF), 0.0) << "LED " << i;
    flash_sum += cv::sum(out_b.flash_linear[i])[0];
  }
  EXPECT_GT(flash_sum, 0.0);
  for (int k = 1; k <= 4; ++k) EXPECT_GT(cv::countNonZero(out_b.part_index == k), 100) << "part " << k;
}

// A render of a region: inside, exactly the whole render's values; outside, nothing there.
static void region_render_equals_the_whole(bool deferred) {
  RenderOptions opt;
  opt.noise.enabled = false;
  opt.deferred_shading = deferred;
  MfcRenderer r(sim_config(), opt);
  const auto parts = mixed_scene(r);
  MfcRender whole, part;
  r.render(parts, whole);
  const cv::Rect regions[] = {{250, 190, 120, 90}, {0, 0, 640, 480}, {600, 0, 40, 480}, {100, 300, 1, 1}};
  for (const cv::Rect& region : regions) {
    r.render(parts, part, 1, region);
    cv::Mat1b outside(part.part_index.size(), uint8_t{255});
    outside(region).setTo(0);
    EXPECT_EQ(cv::norm(part.part_index(region), whole.part_index(region), cv::NORM_INF), 0.0) << region;
    EXPECT_EQ(cv::norm(part.depth_mm(region), whole.depth_mm(region), cv::NORM_INF), 0.0) << region;
    EXPECT_EQ(cv::norm(part.ambient_linear(region), whole.ambient_linear(region), cv::NORM_INF), 0.0) << region;
    EXPECT_EQ(cv::countNonZero(part.part_index & outside), 0) << region;
    EXPECT_EQ(cv::countNonZero((part.depth_mm != 0) & outside), 0) << region;
    for (size_t i = 0; i < 8; ++i) {
      EXPECT_EQ(cv::norm(part.flash_linear[i](region), whole.flash_linear[i](region), cv::NORM_INF), 0.0)
          << region << " LED " << i;
      EXPECT_EQ(cv::countNonZero((part.flash_linear[i] != 0) & outside), 0) << region << " LED " << i;
    }
  }
  EXPECT_THROW(r.render(parts, part, 1, cv::Rect(600, 400, 41, 10)), std::invalid_argument);
}

TEST(MfcRenderer, RegionRenderEqualsTheWholeInsideAndIsEmptyOutside) {
  for (const bool deferred : {false, true}) {
    SCOPED_TRACE(deferred ? "deferred" : "forward");
    region_render_equals_the_whole(deferred);
  }
}

// A render lit only in a mask: in every tile the mask touches, exactly the whole render's
// values; elsewhere nothing there, as outside a region. Lit again with the ring turned (its surfaces reused), or after
// another scene, it is what a renderer that never drew anything else gives.
TEST(MfcRenderer, LitMaskRenderEqualsTheWholeWhereLitAndIsEmptyElsewhere) {
  RenderOptions opt;
  opt.noise.enabled = false;
  opt.deferred_shading = true;
  MfcRenderer r(sim_config(), opt), fresh(sim_config(), opt);
  const auto parts = mixed_scene(r);
  const auto fresh_parts = mixed_scene(fresh);
  cv::Mat1b lit(r.camera().image_size, uint8_t{0});
  cv::circle(lit, {320, 240}, 90, 255, -1);
  cv::rectangle(lit, cv::Rect(0, 0, 640, 7), 255, -1);
  lit(cv::Rect(300, 230, 10, 10)).setTo(0);
  const cv::Rect region(250, 0, 300, 400);
  auto expect_same = [](const MfcRender& a, const MfcRender& b, const char* what) {
    EXPECT_EQ(cv::norm(a.part_index, b.part_index, cv::NORM_INF), 0.0) << what;
    EXPECT_EQ(cv::norm(a.depth_mm, b.depth_mm, cv::NORM_INF), 0.0) << what;
    EXPECT_EQ(cv::norm(a.ambient_linear, b.ambient_linear, cv::NORM_INF), 0.0) << what;
    for (size_t i = 0; i < 8; ++i)
      EXPECT_EQ(cv::norm(a.flash_linear[i], b.flash_linear[i], cv::NORM_INF), 0.0) << what << " LED " << i;
  };
  for (const double turn : {0.0, 0.3}) {
    SCOPED_TRACE(turn);
    const Lighting masked{.ring_turn_rad = turn, .lit = &lit}, all_lit{.ring_turn_rad = turn};
    MfcRender whole, part, again;
    fresh.render(fresh_parts, whole, 1, region, all_lit);
    // What the mask and the region leave out reads as nothing there.
    const cv::Mat1b out_of_region(lit.size(), uint8_t{255});
    out_of_region(region).setTo(0);
    const int tile = MfcRenderer::lit_tile_px(lit.size());
    ASSERT_EQ(tile, 8);
    cv::Mat1b tiles_lit(lit.size(), uint8_t{0});
    for (int y = 0; y < lit.rows; y += tile)
      for (int x = 0; x < lit.cols; x += tile) {
        const cv::Rect t = cv::Rect(x, y, tile, tile) & cv::Rect(cv::Point(), lit.size());
        if (cv::countNonZero(lit(t)) > 0) tiles_lit(t).setTo(255);
      }
    const cv::Mat1b dark = (tiles_lit == 0) | out_of_region;
    for (auto* image : {&whole.ambient_linear, &whole.depth_mm}) image->setTo(0, dark);
    whole.part_index.setTo(0, dark);
    for (auto& f : whole.flash_linear) f.setTo(0, dark);
    r.render(parts, part, 1, region, Lighting{.ring_turn_rad = 1.0});  // other lighting first
    r.render(parts, part, 1, region, masked);
    expect_same(part, whole, "lit again");
    r.render(std::span(parts).first(2), again, 1, region);  // another scene between
    r.render(parts, again, 1, region, masked);
    expect_same(again, whole, "after another scene");
    EXPECT_GT(cv::countNonZero(part.part_index), 1000);
  }
  EXPECT_EQ(MfcRenderer::lit_tile_px({1448, 1448}), 8);  // 181² tiles: 32,761
  EXPECT_EQ(MfcRenderer::lit_tile_px({1449, 1448}), 16);
  MfcRender out;
  const cv::Mat1b small(100, 100, uint8_t{255});
  EXPECT_THROW(r.render(parts, out, 1, {}, Lighting{.lit = &small}), std::invalid_argument);
  RenderOptions forward_opt = opt;
  forward_opt.deferred_shading = false;
  MfcRenderer forward(sim_config(), forward_opt);
  const auto forward_parts = mixed_scene(forward);
  EXPECT_THROW(forward.render(forward_parts, out, 1, {}, Lighting{.lit = &lit}), std::invalid_argument);
}

// Turning a regular ring by its step puts every LED where the next one was: each flash image
// is the next LED's of the unturned ring (to rounding in the shadow maps' placement).
TEST(MfcRenderer, RingTurnedByItsStepLightsAsTheNextLed) {
  const CameraConfig cfg = sim_config();
  ASSERT_TRUE(cfg.flashes.ring);
  for (const bool deferred : {false, true}) {
    SCOPED_TRACE(deferred ? "deferred" : "forward");
    RenderOptions opt;
    opt.noise.enabled = false;
    opt.deferred_shading = deferred;
    MfcRenderer r(cfg, opt);
    const auto parts = mixed_scene(r);
    MfcRender plain, turned;
    r.render(parts, plain);
    r.render(parts, turned, 1, {}, Lighting{.ring_turn_rad = cfg.flashes.ring->step_deg * CV_PI / 180});
    for (size_t i = 0; i < 8; ++i) {
      const cv::Mat1f diff = cv::abs(turned.flash_linear[i] - plain.flash_linear[(i + 1) % 8]);
      EXPECT_LT(cv::countNonZero(diff > 0.5f), 30) << "LED " << i;  // of 307,200 pixels
      EXPECT_GT(cv::norm(turned.flash_linear[i], plain.flash_linear[i], cv::NORM_L1), 1e5) << "LED " << i;
    }
    EXPECT_EQ(cv::norm(turned.ambient_linear, plain.ambient_linear, cv::NORM_INF), 0.0);
  }
}

// Parts all matte are lit by a program without the specular term: the same values.
TEST(MfcRenderer, MatteScenesLightAsForward) {
  RenderOptions deferred_opt, forward_opt;
  deferred_opt.noise.enabled = forward_opt.noise.enabled = false;
  deferred_opt.deferred_shading = true;
  MfcRenderer deferred(sim_config(), deferred_opt), forward(sim_config(), forward_opt);
  auto matte = [](MfcRenderer& r) {
    return std::vector<ScenePart>{
        {r.add_mesh(make_box(40, 30, 30)), rotation(0.4, -0.3, 0.5), {-10, 5, 310}, Material::matte(0.8f)},
        {r.add_mesh(make_plane(800)), cv::Matx33d::eye(), {0, 0, 330}, Material::matte(0.6f), false}};
  };
  const auto a = matte(deferred), b = matte(forward);
  MfcRender out_a, out_b;
  deferred.render(a, out_a);
  forward.render(b, out_b);
  for (size_t i = 0; i < 8; ++i)
    EXPECT_LE(cv::norm(out_a.flash_linear[i], out_b.flash_linear[i], cv::NORM_INF), 1e-4) << "LED " << i;
}

TEST(MfcRenderer, SeveralPartsOccludeAndAreIndexed) {
  MfcRenderer r(sim_config());
  const int cube = r.add_mesh(make_box(30, 30, 30));
  const std::vector<ScenePart> parts = {{cube, cv::Matx33d::eye(), {0, 0, 320}, Material::matte()},
                                        {cube, cv::Matx33d::eye(), {10, 0, 290}, Material::matte()},
                                        {cube, cv::Matx33d::eye(), {-60, 0, 300}, Material::matte()}};
  cv::Mat1f depth;
  cv::Mat1b index;
  r.render_depth(parts, depth, index);
  const cv::Point2d front = r.camera().project({10, 0, 275}), back_only = r.camera().project({-10, 0, 305}),
                    side = r.camera().project({-60, 0, 285});
  EXPECT_EQ(index(cv::Point(front)), 2);
  EXPECT_NEAR(depth(cv::Point(front)), 275.f, 0.01);
  EXPECT_EQ(index(cv::Point(back_only)), 1);
  EXPECT_NEAR(depth(cv::Point(back_only)), 305.f, 0.01);
  EXPECT_EQ(index(cv::Point(side)), 3);
  EXPECT_EQ(index(0, 0), 0);
  EXPECT_EQ(depth(0, 0), 0.f);
}

TEST(MfcRenderer, CroppedCameraRendersTheSameWindow) {
  MfcRenderer r(sim_config());
  const ScenePart part{r.add_mesh(make_uv_sphere(25)), cv::Matx33d::eye(), {10, -5, 300}, Material::matte()};
  MfcRender full, crop;
  r.render(std::span(&part, 1), full);
  const cv::Rect win(200, 120, 180, 150);
  r.set_camera(r.config().camera.cropped(win));
  r.render(std::span(&part, 1), crop);
  EXPECT_LE(cv::norm(crop.depth_mm, full.depth_mm(win), cv::NORM_INF), 1e-3);
  EXPECT_EQ(cv::norm(crop.part_index, full.part_index(win), cv::NORM_INF), 0.0);
  for (int i = 0; i < 8; ++i)
    EXPECT_LE(cv::norm(crop.flash_linear[static_cast<size_t>(i)], full.flash_linear[static_cast<size_t>(i)](win),
                       cv::NORM_INF),
              0.5);
}

// Sensor noise of read sigma 2 DN and shot noise 0.1 DN per electron, and a floor facing the
// camera at 300 mm.
struct NoisyFloor {
  static RenderOptions options() {
    RenderOptions opt;
    opt.noise.read_sigma_dn = 2.0;
    opt.noise.shot_dn_per_electron = 0.1;
    return opt;
  }
  MfcRenderer r{sim_config(), options()};
  const ScenePart floor{r.add_mesh(make_plane(1000)), cv::Matx33d::eye(), {0, 0, 300}, Material::matte(0.6f)};
};

TEST(MfcRenderer, NoiseIsSeededAndOfTheConfiguredSize) {
  NoisyFloor scene;
  MfcRenderer& r = scene.r;
  const ScenePart& floor = scene.floor;
  MfcRender a, b, c;
  r.render(std::span(&floor, 1), a, 42);
  r.render(std::span(&floor, 1), b, 42);
  r.render(std::span(&floor, 1), c, 43);
  for (int i = 0; i < 8; ++i) {
    EXPECT_EQ(cv::norm(a.frames.flash[static_cast<size_t>(i)], b.frames.flash[static_cast<size_t>(i)], cv::NORM_INF),
              0.0);
  }
  EXPECT_GT(cv::norm(a.frames.flash[0], c.frames.flash[0], cv::NORM_L1), 0.0);
  // Residual against the noise-free signal in the image centre: the flat floor is smooth
  // there, so the residual is the sensor noise (plus quantisation, variance 1/12).
  const cv::Rect centre(270, 190, 100, 100);
  cv::Mat1f captured, residual;
  a.frames.flash[0](centre).convertTo(captured, CV_32F);
  cv::subtract(captured, a.flash_linear[0](centre), residual);
  cv::Scalar mean, sd;
  cv::meanStdDev(residual, mean, sd);
  const double signal = cv::mean(a.flash_linear[0](centre))[0];
  const double expected = std::sqrt(4.0 + 0.1 * signal + 1.0 / 12);
  EXPECT_NEAR(mean[0], 0.0, 0.1);
  EXPECT_NEAR(sd[0], expected, 0.1 * expected) << "signal " << signal;
}

// The sensor noise is one seeded draw through each image in turn (the eight flash images, then the
// ambient one), exactly as one cv::RNG::fill of the whole image gives it: generated datasets stay
// the same whichever way the renderer draws it. And a repeated render allocates nothing (the
// simulated camera renders on the daemon's acquisition thread).
TEST(MfcRenderer, NoiseIsOneDrawPerImageAndARepeatedRenderDoesNotAllocate) {
  NoisyFloor scene;
  MfcRenderer& r = scene.r;
  const ScenePart& floor = scene.floor;
  MfcRender out;
  r.render(std::span(&floor, 1), out, 7);
  cv::RNG rng(7);
  cv::Mat1f noise(out.ambient_linear.size());
  auto expect_capture = [&](const cv::Mat1f& signal, const cv::Mat1b& image, const char* what) {
    rng.fill(noise, cv::RNG::NORMAL, 0.0, 1.0);
    int differ = 0;
    for (int y = 0; y < signal.rows; ++y)
      for (int x = 0; x < signal.cols; ++x) {
        const float s = signal(y, x);
        const float v = s + std::sqrt(4.0f + 0.1f * std::max(s, 0.f)) * noise(y, x);
        differ += image(y, x) != static_cast<uint8_t>(std::clamp(std::nearbyint(v), 0.f, 255.f));
      }
    EXPECT_EQ(differ, 0) << what;
  };
  for (size_t i = 0; i < 8; ++i) expect_capture(out.flash_linear[i], out.frames.flash[i], "flash");
  expect_capture(out.ambient_linear, out.frames.ambient, "ambient");

  const auto before = mfcd::hal::test::allocation_count();
  r.render(std::span(&floor, 1), out, 8);
  EXPECT_EQ(mfcd::hal::test::allocation_count() - before, 0u);
}

// Shading: Lambert with inverse-square falloff. A white matte floor facing the camera at
// the working distance, lit by an LED in the lens plane, has the configured brightness
// times the cosine at the image centre.
TEST(MfcRenderer, MatteFloorBrightnessFollowsLambert) {
  RenderOptions opt;
  opt.noise.enabled = false;
  const CameraConfig cfg = sim_config();
  MfcRenderer r(cfg, opt);
  const double wd = cfg.working_distance_mm;
  const ScenePart floor{r.add_mesh(make_plane(1000)), cv::Matx33d::eye(), {0, 0, wd}, Material::matte(1.0f)};
  MfcRender out;
  r.render(std::span(&floor, 1), out);
  const cv::Point c(320, 240);
  const cv::Vec3d P = r.camera().K.inv() * cv::Vec3d(c.x, c.y, 1) * wd;
  for (int i = 0; i < 8; ++i) {
    const cv::Vec3d to_led = cfg.flashes.positions_mm[static_cast<size_t>(i)] - P;
    const double d = cv::norm(to_led);
    const double cosine = -to_led[2] / d;  // floor normal (0, 0, -1) against the light direction
    const double expected = opt.light.flash_dn * (wd * wd) / (d * d) * cosine;
    const double got = out.flash_linear[static_cast<size_t>(i)](c) - out.ambient_linear(c);
    EXPECT_NEAR(got, expected, 0.01 * expected) << "LED " << i;
  }
}
