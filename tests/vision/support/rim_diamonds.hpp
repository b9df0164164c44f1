#pragma once
// Two diamonds standing on their rim: a scene the pipeline and second-look tests share.
#include "vision/pipeline/bin_picking_pipeline.hpp"
#include "vision/pose/coarse_pose.hpp"
#include "vision/pose/rigid_transform.hpp"
#include "vision/render/mfc_renderer.hpp"
#include "vision/templates/template_database.hpp"

#include <array>
#include <filesystem>

namespace mfcd::vision::testing {

// The development parts' templates, built by the mfc_templates target.
inline std::filesystem::path templates_dir() { return std::filesystem::path(MFC_BINARY_DIR) / "templates"; }

// Two diamonds standing on their rim on a floor 300 mm from the camera, seen from above: mfc-sim's
// single parts (seed 3001, scene 2, images 13 and 25), whose spin and depth one view tells poorly.
// Render k shows pose k % 2 with noise seed 31 + k.
struct RimDiamonds {
  CameraConfig cam = load_camera_config(std::filesystem::path(MFC_SOURCE_DIR) / "config/camera-sim.yaml");
  TemplateDatabase db = load_template_database(templates_dir() / "diamond.tdb");
  MfcRenderer renderer{cam};
  int part_id = renderer.add_mesh(db.mesh);
  int floor_id = renderer.add_mesh(make_plane(600));
  std::array<RigidPose, 2> poses;

  RimDiamonds() {
    poses[0].R = cv::Matx33d(-0.6006462866966819, -0.33369238149815655, -0.7265489885806573, -0.6351180848265257,
                             -0.3528433804591809, 0.6871146681540307, -0.48564293117863205, 0.8741572761215377, 0.0);
    poses[0].t_mm = {-29.066912240170723, -15.570549003210616, 282.51685447756927};
    poses[1].R = cv::Matx33d(-0.43822063975722664, -0.24345591097623698, -0.8652698366992214, -0.7563819235591193,
                             -0.4202121797550662, 0.5013064030096787, -0.48564293117863205, 0.8741572761215377, 0.0);
    poses[1].t_mm = {13.774532223156854, 15.14256529831681, 282.51685447756927};
  }
  PipelineConfig config() const {
    PipelineConfig pc;
    pc.template_files = {templates_dir() / "diamond.tdb"};
    pc.floor.distance_mm = 300;
    return pc;
  }
  const RigidPose& truth(int k) const { return poses[static_cast<size_t>(k % 2)]; }
  // Seen by the camera after `motion` (first camera's frame -> the moved camera's): the second look.
  MfcRender render(int k, const RigidTransform& motion = {}) {
    const RigidPose& p = truth(k);
    const ScenePart parts[2] = {
        {part_id, motion.R * p.R, motion.R * p.t_mm + motion.t, Material::matte(0.6f)},
        {floor_id, motion.R, motion.R * cv::Vec3d(0, 0, 300) + motion.t, Material::matte(0.5f)}};
    MfcRender out;
    renderer.render(parts, out, 31 + static_cast<uint64_t>(k));
    return out;
  }
};

}  // namespace mfcd::vision::testing
