// The frame path's undistortion (vision/camera/frame_undistorter) end to end: a part rendered by
// the ideal pinhole, the nine images warped by a known barrel distortion as a real lens would
// show them, undistorted with the camera's maps and picked by the pipeline within the same bounds
// (5 mm, 10 degrees) as the undistorted render. Without the undistortion the edges near the
// image corners are several pixels off and the pick is worse: the test can fail.
#include "tests/vision/support/floor_scene.hpp"
#include "tests/vision/support/pose_errors.hpp"
#include "vision/camera/frame_undistorter.hpp"
#include "vision/pipeline/bin_picking_pipeline.hpp"
#include "vision/pose/coarse_pose.hpp"
#include "vision/render/mfc_renderer.hpp"
#include "vision/templates/template_database.hpp"

#include <gtest/gtest.h>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <chrono>
#include <cstdio>
#include <filesystem>

using namespace mfcd::vision;
namespace fs = std::filesystem;

namespace {

const fs::path kTemplates = fs::path(MFC_BINARY_DIR) / "templates";

// A realistic barrel for the simulated camera's lens (OpenCV order k1 k2 p1 p2 k3).
const std::vector<double> kBarrel = {-0.5, 0.2, 0.0, 0.0, 0.0};

// What the lens makes of an ideal image: distorted(p_d) = ideal(p_u), p_u = the ideal (pinhole)
// pixel whose ray the lens bends onto the distorted pixel p_d. cv::undistortPoints (P = K) gives
// p_u from p_d, i.e. the inverse of the forward model that initUndistortRectifyMap evaluates,
// so this is the exact inverse of FrameUndistorter's mapping (up to the iteration's 1e-10).
// Outside the ideal image (the distorted corners see further out): the nearest edge pixel.
class LensSimulator {
 public:
  explicit LensSimulator(const PinholeCamera& cam) {
    std::vector<cv::Point2f> distorted;
    distorted.reserve(static_cast<size_t>(cam.image_size.area()));
    for (int y = 0; y < cam.image_size.height; ++y)
      for (int x = 0; x < cam.image_size.width; ++x)
        distorted.emplace_back(static_cast<float>(x), static_cast<float>(y));
    std::vector<cv::Point2f> ideal;
    cv::undistortPoints(distorted, ideal, cv::Mat(cam.K), cv::Mat(cam.distortion), cv::noArray(), cv::Mat(cam.K),
                        cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-10));
    mapx_.create(cam.image_size);
    mapy_.create(cam.image_size);
    for (int y = 0, i = 0; y < cam.image_size.height; ++y)
      for (int x = 0; x < cam.image_size.width; ++x, ++i) {
        mapx_(y, x) = ideal[static_cast<size_t>(i)].x;
        mapy_(y, x) = ideal[static_cast<size_t>(i)].y;
      }
  }
  cv::Point2f ideal_of(cv::Point p) const { return {mapx_(p), mapy_(p)}; }
  MfcFrames distort(const MfcFrames& ideal) const {
    MfcFrames out;
    for (const auto& f : ideal.flash) out.flash.push_back(warp(f));
    out.ambient = warp(ideal.ambient);
    return out;
  }

 private:
  cv::Mat1b warp(const cv::Mat1b& in) const {
    cv::Mat1b out;
    cv::remap(in, out, mapx_, mapy_, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    return out;
  }
  cv::Mat1f mapx_, mapy_;
};

MfcFrames undistort(const FrameUndistorter& u, const MfcFrames& in) {
  MfcFrames out;
  for (const auto& f : in.flash) {
    cv::Mat m;
    u.apply(f, m);
    out.flash.push_back(m);
  }
  cv::Mat m;
  u.apply(in.ambient, m);
  out.ambient = m;
  return out;
}

struct PickError {
  bool found = false;
  double centre_mm = 1e9;
  double rotation_deg = 1e9;
};

using mfcd::vision::testing::rotation_error_deg;

PickError pick(BinPickingPipeline& pipeline, const MfcFrames& frames, const TemplateDatabase& db,
               const RigidPose& truth) {
  PipelineResult r;
  pipeline.process(frames, 0, std::chrono::steady_clock::now() + std::chrono::seconds(60), r);
  PickError e;
  if (r.candidates.empty()) return e;
  const PoseCandidate& c = r.candidates.front();
  e.found = true;
  e.centre_mm = cv::norm(c.R_m2c * db.center_mm + c.t_m2c_mm - (truth.R * db.center_mm + truth.t_mm));
  e.rotation_deg = rotation_error_deg(c.R_m2c, truth.R, db.symmetry);
  return e;
}

}  // namespace

TEST(UndistortedPick, DistortedRenderUndistortedIsPickedAsTheIdealOne) {
  const fs::path tdb = kTemplates / "tnut.tdb";
  ASSERT_TRUE(fs::exists(tdb)) << tdb;
  const TemplateDatabase db = load_template_database(tdb);
  const CameraConfig ideal_cam = load_camera_config(fs::path(MFC_SOURCE_DIR) / "config/camera-sim.yaml");
  CameraConfig lens_cam = ideal_cam;  // the same K: the calibrated camera of a real lens
  lens_cam.camera.distortion = kBarrel;

  // The part towards the lower right corner, where the lens bends its edges most.
  int view = 0;
  while (db.views[static_cast<size_t>(view)].view_direction[2] < 0.5) ++view;
  const RigidPose truth = coarse_pose(db, TemplatePlacement{view, 0.6, 1.0, {470, 340}}, ideal_cam.camera);
  MfcRenderer renderer(ideal_cam);
  const int part_id = renderer.add_mesh(db.mesh);
  const int floor_id = renderer.add_mesh(make_plane(600));
  const MfcRender render = mfcd::vision::testing::render_on_floor(renderer, part_id, floor_id, db, truth, 17);

  const LensSimulator lens(lens_cam.camera);
  const MfcFrames distorted = lens.distort(render.frames);
  const FrameUndistorter undistorter(lens_cam.camera);
  ASSERT_TRUE(undistorter.active());
  const auto t0 = std::chrono::steady_clock::now();
  const MfcFrames corrected = undistort(undistorter, distorted);
  std::printf("undistorting 9 images (allocating): %.2f ms\n",
              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());

  // The lens really moves the image: near the corner by more than 10 px, at the part by several.
  EXPECT_GT(cv::norm(lens.ideal_of({630, 470}) - cv::Point2f(630, 470)), 10.0);
  const cv::Point2f part_px(470, 340);
  const double at_part = cv::norm(lens.ideal_of(part_px) - part_px);
  std::printf("lens displacement at the part's centre: %.2f px\n", at_part);
  EXPECT_GT(at_part, 2.0);
  // Undistorting the distorted render gives back the ideal one (both remaps blur a little; the
  // corners the lens shows beyond the ideal field of view are not compared).
  cv::Mat diff;
  cv::absdiff(corrected.ambient, render.frames.ambient, diff);
  const cv::Rect inner(20, 20, 600, 440);
  EXPECT_LT(cv::mean(diff(inner))[0], 2.0);

  PipelineConfig pc;
  pc.template_files = {tdb};
  BinPickingPipeline pipeline(ideal_cam, pc);
  const PickError ideal = pick(pipeline, render.frames, db, truth);
  const PickError fixed = pick(pipeline, corrected, db, truth);
  const PickError raw = pick(pipeline, distorted, db, truth);
  std::printf(
      "pick error: ideal render %.2f mm %.2f deg; distorted + undistorted %.2f mm %.2f deg; "
      "distorted as is %.2f mm %.2f deg\n",
      ideal.centre_mm, ideal.rotation_deg, fixed.centre_mm, fixed.rotation_deg, raw.centre_mm, raw.rotation_deg);
  ASSERT_TRUE(ideal.found);
  EXPECT_LE(ideal.centre_mm, 5.0);
  EXPECT_LE(ideal.rotation_deg, 10.0);
  ASSERT_TRUE(fixed.found);
  EXPECT_LE(fixed.centre_mm, 5.0);
  EXPECT_LE(fixed.rotation_deg, 10.0);
  // Without the undistortion the same frame is picked worse, outside the bounds (the lens makes
  // the part look ~4 % smaller there: too far away).
  EXPECT_GT(raw.centre_mm, fixed.centre_mm + 1.0);
  EXPECT_GT(raw.centre_mm, 5.0);
}
