#include "tools/eval/refine_eval.hpp"

#include <stdexcept>

#if __has_include("vision/pose/pose_refiner.hpp")
#define MFC_EVAL_HAS_REFINER 1
#include "tools/common/build_version.hpp"
#include "tools/eval/pose_error.hpp"
#include "vision/edges/depth_edges.hpp"
#include "vision/pipeline/bin_picking_pipeline.hpp"
#include "vision/pose/pose_refiner.hpp"
#include "vision/render/mfc_renderer.hpp"
#include "vision/templates/template_database.hpp"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#endif

namespace mfcd::eval {

#ifndef MFC_EVAL_HAS_REFINER
bool refine_eval_available() { return false; }
int run_refine_eval(const RefineEvalOptions&) {
  throw std::runtime_error(
      "refine (Table 2): this build has no multi-view refiner (vision/pose/pose_refiner.hpp); "
      "Table 2 is measured once it lands on main");
}
#else
bool refine_eval_available() { return true; }

namespace {

using vision::RigidTransform;

// Camera 1 relative to camera 0: its centre `shift` sideways (+x of camera 0), its optical
// axis through `target` (camera 0 frame), its x axis as close to camera 0's as possible.
RigidTransform second_camera(const cv::Vec3d& target, double shift) {
  const cv::Vec3d c(shift, 0, 0);
  const cv::Vec3d z = cv::normalize(target - c);
  const cv::Vec3d x = cv::normalize(cv::Vec3d(1, 0, 0) - z * z[0]);
  const cv::Vec3d y = z.cross(x);
  const cv::Matx33d R(x[0], x[1], x[2], y[0], y[1], y[2], z[0], z[1], z[2]);
  return {R, -(R * c)};
}

cv::Matx33d random_rotation(std::mt19937& rng) {
  // Uniform on SO(3): a unit quaternion from four normals.
  std::normal_distribution<double> n;
  cv::Vec4d q(n(rng), n(rng), n(rng), n(rng));
  q = q / cv::norm(q);
  const double w = q[0], x = q[1], y = q[2], z = q[3];
  return {1 - 2 * (y * y + z * z), 2 * (x * y - z * w),     2 * (x * z + y * w),
          2 * (x * y + z * w),     1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
          2 * (x * z - y * w),     2 * (y * z + x * w),     1 - 2 * (x * x + y * y)};
}

nlohmann::json error_json(const PoseError& e) {
  return {{"t", {e.abs_t_mm[0], e.abs_t_mm[1], e.abs_t_mm[2]}},
          {"r", {e.abs_r_deg[0], e.abs_r_deg[1], e.abs_r_deg[2]}},
          {"position_mm", e.position_mm},
          {"rotation_deg", e.rotation_deg}};
}

}  // namespace

int run_refine_eval(const RefineEvalOptions& o) {
  using namespace vision;
  const CameraConfig cam = load_camera_config(o.camera);
  const std::vector<PartEntry> parts = read_parts_csv(o.parts);
  MfcRenderer renderer(cam);
  const int floor_mesh = renderer.add_mesh(make_plane(800));
  DepthEdgeExtractor extractor(cam.camera, cam.flashes);
  std::mt19937 rng(o.seed);
  std::uniform_real_distribution<double> u(-1, 1);
  const Criterion criterion;
  nlohmann::json trials = nlohmann::json::array();
  for (const PartEntry& part : parts) {
    const std::filesystem::path tdb = o.templates / (part.name + ".tdb");
    if (!std::filesystem::is_regular_file(tdb))
      throw std::runtime_error(tdb.string() + ": no template file for part '" + part.name + "'");
    const TemplateDatabase db = load_template_database(tdb);
    PipelineConfig pc;
    pc.template_files = {tdb};
    pc.distances_mm = o.distances_mm;
    pc.refine_candidates = 0;  // the coarse pose (Sec. 4.4); both refinements start from it
    BinPickingPipeline pipeline(cam, pc);
    const int mesh = renderer.add_mesh(db.mesh);
    const PoseModel model = pose_model(mesh, db.mesh);
    RefinerParams rp;
    PoseRefiner refiner(renderer, rp);
    for (int trial = 0; trial < o.trials_per_part; ++trial) {
      // A random orientation, the part centre at a random place under the camera.
      RigidTransform truth;
      truth.R = random_rotation(rng);
      const cv::Vec3d centre(25 * u(rng), 20 * u(rng), 292 + 8 * u(rng));
      truth.t = centre - truth.R * db.center_mm;
      const RigidTransform floor{cv::Matx33d::eye(), {0, 0, centre[2] + db.diameter_mm / 2 + 10}};
      const RigidTransform cam1 = second_camera(centre, o.side_shift_mm);
      MfcRender r0, r1;
      DepthEdges e0, e1;
      renderer.set_camera(cam.camera);
      ScenePart scene[2] = {{mesh, truth.R, truth.t, Material::matte(0.6f)},
                            {floor_mesh, floor.R, floor.t, Material::matte(0.5f)}};
      renderer.render(scene, r0, 1000 + static_cast<uint64_t>(trial));
      const RigidTransform p1 = cam1 * truth, f1 = cam1 * floor;
      scene[0].R = p1.R, scene[0].t_mm = p1.t;
      scene[1].R = f1.R, scene[1].t_mm = f1.t;
      renderer.render(scene, r1, 2000 + static_cast<uint64_t>(trial));
      extractor.extract(r0.frames, e0);
      extractor.extract(r1.frames, e1);

      PipelineResult coarse;
      pipeline.process(r0.frames, part.obj_id, std::chrono::steady_clock::now() + std::chrono::hours(1), coarse);
      nlohmann::json t = {{"part", part.name}, {"obj_id", part.obj_id}, {"trial", trial}};
      if (coarse.candidates.empty()) {
        t["coarse_found"] = false;
        trials.push_back(t);
        continue;
      }
      const RigidTransform initial{coarse.candidates[0].R_m2c, coarse.candidates[0].t_m2c_mm};
      const PoseError ec = pose_error(initial.R, initial.t, truth.R, truth.t, part.symmetry, db.center_mm);
      t["coarse_found"] = true;
      t["coarse"] = error_json(ec);
      t["coarse_correct"] = criterion.accepts(ec);
      const RefinementView views[2] = {{&e0, cam.camera, RigidTransform{}}, {&e1, cam.camera, cam1}};
      for (int n = 1; n <= 2; ++n) {
        const auto t0 = std::chrono::steady_clock::now();
        refiner.prepare({views, static_cast<size_t>(n)});
        const RefinementResult rr = refiner.refine(model, initial);
        const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        const PoseError e = pose_error(rr.pose.R, rr.pose.t, truth.R, truth.t, part.symmetry, db.center_mm);
        nlohmann::json j = error_json(e);
        j["ms"] = ms;
        j["converged"] = rr.converged;
        j["failed"] = rr.failed;
        j["score"] = rr.score;
        t[n == 1 ? "view1" : "view2"] = j;
      }
      if (!o.quiet)
        std::fprintf(stderr,
                     "%s trial %d: coarse %.1f mm %.1f deg -> 1 view %.2f mm %.2f deg, 2 views %.2f mm %.2f deg\n",
                     part.name.c_str(), trial, ec.position_mm, ec.rotation_deg, t["view1"]["position_mm"].get<double>(),
                     t["view1"]["rotation_deg"].get<double>(), t["view2"]["position_mm"].get<double>(),
                     t["view2"]["rotation_deg"].get<double>());
      trials.push_back(t);
    }
  }
  nlohmann::json out = {{"version", version()},
                        {"commit", git_commit()},
                        {"seed", o.seed},
                        {"trials_per_part", o.trials_per_part},
                        {"side_shift_mm", o.side_shift_mm},
                        {"camera", o.camera.string()},
                        {"distances_mm", o.distances_mm},
                        {"trials", trials}};
  const std::filesystem::path tmp = o.out.string() + ".tmp";
  {
    std::ofstream f(tmp);
    if (!f) throw std::runtime_error(tmp.string() + ": cannot create");
    f << out.dump(1) << "\n";
    if (!f) throw std::runtime_error(tmp.string() + ": write failed");
  }
  std::filesystem::rename(tmp, o.out);
  std::printf("wrote %s\n", o.out.c_str());
  return 0;
}
#endif

}  // namespace mfcd::eval
