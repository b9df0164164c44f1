// The simulated cell end to end: MfcSequencer drives SimulatedLightRing + SimulatedCamera, the
// camera renders real meshes with the multi-flash renderer, and the FrameSet it produces yields
// depth edges on the true depth discontinuities (paper Sec. 4.2).
#include <gtest/gtest.h>

#include "mfcd/hal/rendered_cell_scene.hpp"
#include "mfcd/hal/sequencer.hpp"
#include "vision/camera/camera.hpp"
#include "vision/edges/depth_edges.hpp"
#include "vision/edges/edge_evaluation.hpp"
#include "vision/model/mesh.hpp"

using namespace mfcd;

namespace {
vision::CameraConfig small_camera() {
  vision::CameraConfig cfg = vision::load_camera_config(MFC_SOURCE_DIR "/config/camera-sim.yaml");
  cfg.camera.image_size = {320, 240};
  cfg.camera.K = cv::Matx33d(cfg.camera.fx() / 2, 0, 160, 0, cfg.camera.fy() / 2, 120, 0, 0, 1);
  return cfg;
}
cv::Mat1b view(const hal::Image& img) {
  return cv::Mat1b(img.format().height, img.format().width, const_cast<uint8_t*>(img.data()));
}
}  // namespace

TEST(RenderedCellScene, SequencerCapturesTheRenderedCellInLockstep) {
  const vision::CameraConfig cfg = small_camera();
  std::unique_ptr<vision::MfcRenderer> renderer;
  try {
    renderer = std::make_unique<vision::MfcRenderer>(cfg);
  } catch (const std::runtime_error& e) {
    GTEST_SKIP() << "no offscreen OpenGL here: " << e.what();
  }
  const double c = std::cos(0.4), s = std::sin(0.4);
  std::vector<vision::ScenePart> parts{
      {renderer->add_mesh(vision::make_plane(800)), cv::Matx33d::eye(), {0, 0, 330}, vision::Material::matte(0.6f)},
      {renderer->add_mesh(vision::make_box(50, 35, 30)),
       cv::Matx33d(c, -s, 0, s, c, 0, 0, 0, 1),
       {5, -3, 315},
       vision::Material::matte(0.8f)}};
  hal::RenderedCellScene cell(*renderer, parts);
  hal::SimulatedLightRing ring;
  hal::SimulatedCamera camera({{320, 240, 8}, "sim-cell", 0}, ring, &cell);
  hal::MfcSequencer seq(camera, ring);
  seq.configure();
  seq.activate();
  const hal::FrameSet& set = seq.read();
  const hal::FrameSet& set2 = seq.read();
  EXPECT_EQ(set2.sequence, 2u);
  EXPECT_EQ(cell.renders(), 2u) << "one render per FrameSet";

  // Each slot holds exactly the render of its LED (slot 8: ambient).
  const vision::MfcRender& r = cell.last_render();
  for (int k = 0; k < hal::kLedCount; ++k)
    EXPECT_EQ(cv::countNonZero(view(set2.frames[k].image) != r.frames.flash[k]), 0) << "LED " << k;
  EXPECT_EQ(cv::countNonZero(view(set2.frames[8].image) != r.frames.ambient), 0);
  // The box casts a different shadow for every LED.
  for (int k = 1; k < hal::kLedCount; ++k)
    EXPECT_GT(cv::countNonZero(view(set2.frames[k].image) != view(set2.frames[0].image)), 100) << "LED " << k;

  // Depth edges from the captured FrameSet lie on the box's true silhouette.
  vision::MfcFrames frames;
  for (int k = 0; k < hal::kLedCount; ++k) frames.flash.push_back(view(set2.frames[k].image).clone());
  frames.ambient = view(set2.frames[8].image).clone();
  vision::DepthEdgeExtractor extractor(cfg.camera, cfg.flashes);
  vision::DepthEdges edges;
  extractor.extract(frames, edges);
  const cv::Mat1b truth = vision::depth_discontinuities(r.depth_mm, 4.0f);
  const vision::EdgeScore score = vision::score_edges(edges.edges, truth, 1.0);
  EXPECT_GT(score.truth, 150);
  EXPECT_GE(score.precision, 0.8);
  EXPECT_GE(score.recall, 0.8);
  std::printf("simulated cell depth edges: precision %.3f recall %.3f (%d truth pixels)\n", score.precision,
              score.recall, score.truth);
  seq.deactivate();
  (void)set;
}
