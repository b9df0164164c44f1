#pragma once
// Simulated bin scenes shared by the depth-edge tests and benchmark: a floor and several
// parts at seeded random poses, some painted with stripes or checkers.
#include "vision/render/mfc_renderer.hpp"

#include <cmath>
#include <random>

namespace mfcd::vision::testing {

inline cv::Matx33d rotation(const cv::Vec3d& w) {
  const double th = cv::norm(w);
  if (th < 1e-15) return cv::Matx33d::eye();
  const cv::Vec3d k = w / th;
  const cv::Matx33d Kx(0, -k[2], k[1], k[2], 0, -k[0], -k[1], k[0], 0);
  return cv::Matx33d::eye() + std::sin(th) * Kx + (1 - std::cos(th)) * Kx * Kx;
}

struct SceneMeshes {
  int floor, box, cylinder, flat_box, sphere;
  explicit SceneMeshes(MfcRenderer& r)
      : floor(r.add_mesh(make_plane(1000))),
        box(r.add_mesh(make_box(40, 28, 18))),
        cylinder(r.add_mesh(make_cylinder(16, 30, 96))),
        flat_box(r.add_mesh(make_box(60, 36, 10))),
        sphere(r.add_mesh(make_uv_sphere(14, 96, 48))) {}
};

// Parts lie on (or lean on) a floor 345 mm from the camera; `painted` paints every part.
inline std::vector<ScenePart> random_scene(const SceneMeshes& m, uint32_t seed, bool painted) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<ScenePart> parts{{m.floor, cv::Matx33d::eye(), {0, 0, 345}, Material::matte(0.55f)}};
  const int meshes[4] = {m.box, m.cylinder, m.flat_box, m.sphere};
  const double half_height[4] = {9, 15, 5, 14};
  const cv::Vec2d spots[4] = {{-55, -35}, {50, -40}, {-45, 45}, {55, 40}};
  for (int k = 0; k < 4; ++k) {
    const double tilt = 0.35;
    const cv::Matx33d R = rotation({tilt * u(rng), tilt * u(rng), 3.1 * u(rng)});
    const cv::Vec3d t(spots[k][0] + 8 * u(rng), spots[k][1] + 8 * u(rng),
                      345 - half_height[k] - 4 - 6 * std::abs(u(rng)));
    Material mat = Material::matte(0.6f + 0.3f * static_cast<float>(std::abs(u(rng))));
    if (painted) {
      mat.paint = (k % 2) ? Material::Paint::checker : Material::Paint::stripes;
      mat.paint_period_mm = 5.0f;
      mat.paint_albedo = 0.15f;
    }
    parts.push_back({meshes[k], R, t, mat});
  }
  return parts;
}

}  // namespace mfcd::vision::testing
