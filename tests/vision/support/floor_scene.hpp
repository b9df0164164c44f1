#pragma once
// One rendered part over a floor, seen by the simulated MFC: the scene the pipeline and the
// pose-fit tests both look at. Header-only, so that the test support library need not link the
// renderer (only the tests that render include this).
#include "vision/pose/coarse_pose.hpp"
#include "vision/render/mfc_renderer.hpp"
#include "vision/templates/template_database.hpp"

namespace mfcd::vision::testing {

// The part at `pose` (model -> camera) on a floor 10 mm below its bounding sphere.
inline MfcRender render_on_floor(MfcRenderer& renderer, int part_id, int floor_id, const TemplateDatabase& db,
                                 const RigidPose& pose, uint64_t seed) {
  const cv::Vec3d centre = pose.R * db.center_mm + pose.t_mm;
  const ScenePart parts[2] = {
      {part_id, pose.R, pose.t_mm, Material::matte(0.6f)},
      {floor_id, cv::Matx33d::eye(), {0, 0, centre[2] + db.diameter_mm / 2 + 10}, Material::matte(0.5f)}};
  MfcRender render;
  renderer.render(parts, render, seed);
  return render;
}

}  // namespace mfcd::vision::testing
