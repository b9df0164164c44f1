// ShadingCheck: the flashes' shares of light at a pose against the images', on scenes rendered by
// MfcRenderer (with sensor noise), and the windowed comparison against the whole-image one.
#include "vision/pose/shading_check.hpp"
#include "pose_scenes.hpp"
#include "vision/model/mesh.hpp"

#include <gtest/gtest.h>

#include <stdexcept>

using namespace mfcd::vision;
using mfcd::vision::testing::sim_config;

namespace {

// A box lying tilted on a floor 40 mm behind it, its top face turned towards the flashes on one side.
struct TiltedBox {
  CameraConfig config = sim_config();
  MfcRenderer renderer{config};
  Mesh box = make_box(40, 30, 12);
  int box_id = renderer.add_mesh(box);
  int floor_id = renderer.add_mesh(make_plane(400));
  PoseModel model = pose_model(box_id, box);
  RigidTransform truth;

  TiltedBox() {
    truth.R =
        rotation_from_angle_axis(cv::Vec3d(radians(25), 0, 0)) * rotation_from_angle_axis(cv::Vec3d(0, radians(10), 0));
    truth.t = cv::Vec3d(12, -8, config.working_distance_mm - 20);
  }
  // The images of the scene, the box of the given albedo.
  MfcFrames frames(float albedo = 0.7f) {
    renderer.set_camera(config.camera);
    const ScenePart parts[2] = {
        {box_id, truth.R, truth.t, Material::matte(albedo)},
        {floor_id, cv::Matx33d::eye(), cv::Vec3d(0, 0, config.working_distance_mm + 20), Material::matte(0.5f), false}};
    MfcRender out;
    renderer.render(parts, out, 7);
    return out.frames;
  }
  // The pose turned by `deg` about the camera axis `axis` through the box's centre.
  RigidTransform turned(const cv::Vec3d& axis, double deg) const {
    const cv::Matx33d dR = rotation_from_angle_axis(axis * radians(deg));
    RigidTransform p;
    p.R = dR * truth.R;
    p.t = truth.t;  // the box's centre is its model origin
    return p;
  }
};

TEST(ShadingCheck, TheTruePoseAgreesBetterThanTheSamePoseTiltedBy15Degrees) {
  TiltedBox scene;
  const MfcFrames frames = scene.frames();
  ShadingCheck check(scene.renderer);
  const ShadingAgreement truth = check.compare(frames, scene.config.camera, scene.model, scene.truth);
  EXPECT_GT(truth.pixels, 1000);
  EXPECT_LT(truth.error, 0.05) << "sensor noise alone";
  for (const cv::Vec3d& axis : {cv::Vec3d(1, 0, 0), cv::Vec3d(0, 1, 0)})
    for (const double deg : {-15.0, 15.0}) {
      const ShadingAgreement tilted = check.compare(frames, scene.config.camera, scene.model, scene.turned(axis, deg));
      EXPECT_GT(tilted.pixels, 500);
      EXPECT_GT(tilted.error, 1.4 * truth.error) << "tilted " << deg << " deg about " << axis;
    }
}

TEST(ShadingCheck, DoesNotDependOnTheSurfacesAlbedo) {
  TiltedBox scene;
  ShadingCheck check(scene.renderer);
  for (const float albedo : {0.35f, 0.9f}) {
    const MfcFrames frames = scene.frames(albedo);
    const ShadingAgreement truth = check.compare(frames, scene.config.camera, scene.model, scene.truth);
    EXPECT_GT(truth.pixels, 1000) << "albedo " << albedo;
    EXPECT_LT(truth.error, 0.06) << "albedo " << albedo;
  }
}

TEST(ShadingCheck, TheWindowAgreesWithTheWholeImage) {
  TiltedBox scene;
  const MfcFrames frames = scene.frames();
  ShadingCheck check(scene.renderer);
  for (const RigidTransform& pose : {scene.truth, scene.turned(cv::Vec3d(1, 0, 0), 12)}) {
    const ShadingAgreement window = check.compare(frames, scene.config.camera, scene.model, pose);
    const ShadingAgreement whole = check.compare_whole_image(frames, scene.config.camera, scene.model, pose);
    EXPECT_NEAR(window.pixels, whole.pixels, 0.02 * whole.pixels);
    EXPECT_NEAR(window.error, whole.error, 0.05 * whole.error + 1e-3);
  }
}

TEST(ShadingCheck, APartOutsideTheImageComparesNothing) {
  TiltedBox scene;
  const MfcFrames frames = scene.frames();
  ShadingCheck check(scene.renderer);
  RigidTransform away = scene.truth;
  away.t[0] += 2000;
  const ShadingAgreement a = check.compare(frames, scene.config.camera, scene.model, away);
  EXPECT_EQ(a.pixels, 0);
  EXPECT_EQ(a.error, 0);
}

TEST(ShadingCheck, RefusesImagesWithoutEveryFlashAndBadParameters) {
  TiltedBox scene;
  MfcFrames frames = scene.frames();
  frames.flash.pop_back();
  ShadingCheck check(scene.renderer);
  EXPECT_THROW(check.compare(frames, scene.config.camera, scene.model, scene.truth), std::invalid_argument);
  ShadingParams p;
  p.keep_fraction = 0;
  EXPECT_THROW(p.validate(), std::invalid_argument);
  p = {};
  p.min_flash_ratio = 1;
  EXPECT_THROW(ShadingCheck(scene.renderer, p), std::invalid_argument);
}

}  // namespace
