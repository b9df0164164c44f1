// The region a teaching render draws: it holds every pixel the part or its shadows change.
#include "vision/templates/render_window.hpp"
#include "vision/render/mfc_renderer.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace mfcd::vision;

namespace {

CameraConfig sim_config() { return load_camera_config(MFC_SOURCE_DIR "/config/camera-sim.yaml"); }

cv::Matx33d turn(double rx, double ry, double rz) {
  cv::Matx33d R = cv::Matx33d::eye();
  const double a[3] = {rx, ry, rz};
  for (int k = 0; k < 3; ++k) {
    const double c = std::cos(a[k]), s = std::sin(a[k]);
    cv::Matx33d Q = cv::Matx33d::eye();
    const int i = (k + 1) % 3, j = (k + 2) % 3;
    Q(i, i) = c, Q(i, j) = -s, Q(j, i) = s, Q(j, j) = c;
    R = Q * R;
  }
  return R;
}

}  // namespace

TEST(PartRegion, HoldsThePartAndEveryShadowItCasts) {
  const CameraConfig cfg = sim_config();
  RenderOptions opt;
  opt.noise.enabled = false;
  MfcRenderer r(cfg, opt);
  const Mesh rod = make_cylinder(5, 70, 48);
  const int rod_id = r.add_mesh(rod);
  const int plane_id = r.add_mesh(make_plane(2000));
  const double far = 340;
  const ScenePart plane{plane_id, cv::Matx33d::eye(), {0, 0, far}, Material::matte(0.6f), false};
  MfcRender empty, with_part;
  r.render(std::span(&plane, 1), empty);
  const cv::Rect whole(cv::Point(0, 0), cfg.camera.image_size);
  const struct {
    cv::Matx33d R;
    cv::Vec3d t;
  } poses[] = {{turn(1.2, 0.3, 0.2), {0, 0, 290}}, {turn(0.1, 1.5, 0.7), {-20, 15, 300}}, {turn(0, 0, 0), {0, 0, 280}}};
  for (const auto& pose : poses) {
    const cv::Rect region = part_region(cfg, cfg.camera, rod, pose.R, pose.t, far);
    ASSERT_FALSE(region.empty());
    EXPECT_LT(region.area(), whole.area() / 3) << "a thin rod needs a small part of the image";
    const ScenePart scene[2] = {{rod_id, pose.R, pose.t, Material::matte()}, plane};
    r.render(scene, with_part);
    int changed = 0, outside = 0;
    for (int y = 0; y < whole.height; ++y)
      for (int x = 0; x < whole.width; ++x) {
        bool differs = with_part.part_index(y, x) == 1;  // the rod
        for (size_t i = 0; i < 8; ++i)
          differs |= std::abs(with_part.flash_linear[i](y, x) - empty.flash_linear[i](y, x)) > 0.5f;
        changed += differs;
        outside += differs && !region.contains({x, y});
      }
    EXPECT_GT(changed, 1000);
    EXPECT_EQ(outside, 0) << region;
  }
}
