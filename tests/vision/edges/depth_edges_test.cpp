#include "vision/edges/depth_edges.hpp"
#include "vision/common/orientation.hpp"
#include "vision/edges/edge_evaluation.hpp"

#include "scenes.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <numbers>
#include <random>

using namespace mfcd::vision;
using mfcd::vision::testing::random_scene;
using mfcd::vision::testing::SceneMeshes;

namespace {

CameraConfig sim_config() { return load_camera_config(MFC_SOURCE_DIR "/config/camera-sim.yaml"); }

// The slow, obviously-right twin of DepthEdgeExtractor: whole-image OpenCV operations,
// per-pixel directions from the epipole, NMS by explicit comparisons and hysteresis by
// repeated dilation until nothing changes.
DepthEdges reference_depth_edges(const MfcFrames& frames, const PinholeCamera& cam, const FlashRing& flashes,
                                 const DepthEdgeParams& p) {
  const cv::Size size = cam.image_size;
  const size_t n = flashes.positions_mm.size();
  std::vector<cv::Mat1f> I(n);
  cv::Mat1f ambient, Imax(size, 0.f);
  frames.ambient.convertTo(ambient, CV_32F);
  for (size_t i = 0; i < n; ++i) {
    frames.flash[i].convertTo(I[i], CV_32F);
    I[i] = cv::max(I[i] - ambient, 0.f);
    Imax = cv::max(Imax, I[i]);
  }
  cv::Mat1f S(size, 0.f), Nx(size, 0.f), Ny(size, 0.f);
  for (size_t i = 0; i < n; ++i) {
    cv::Mat1f R(size);
    for (int y = 0; y < size.height; ++y)
      for (int x = 0; x < size.width; ++x) R(y, x) = Imax(y, x) >= p.min_flash_dn ? I[i](y, x) / Imax(y, x) : 1.f;
    cv::Mat1f gx, gy;
    cv::Sobel(R, gx, CV_32F, 1, 0, 3, 0.25);
    cv::Sobel(R, gy, CV_32F, 0, 1, 3, 0.25);
    const FlashEpipole e = flash_epipole(cam, flashes.positions_mm[i]);
    for (int y = 1; y + 1 < size.height; ++y)
      for (int x = 1; x + 1 < size.width; ++x) {
        const cv::Vec2d d = cv::normalize(e.shadow_direction(x, y));
        const double along = -(gx(y, x) * d[0] + gy(y, x) * d[1]);
        if (along > 0) {
          S(y, x) += static_cast<float>(along);
          Nx(y, x) -= static_cast<float>(along) * gx(y, x);
          Ny(y, x) -= static_cast<float>(along) * gy(y, x);
        }
      }
  }
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x) {
      const float m = Imax(y, x);
      S(y, x) *= m * m / (m * m + p.dim_flash_dn * p.dim_flash_dn);
    }
  cv::Mat1b weak(size, 0), strong(size, 0);
  for (int y = 2; y + 2 < size.height; ++y)
    for (int x = 2; x + 2 < size.width; ++x) {
      if (S(y, x) < p.low_threshold) continue;
      // Nearest of the 8 neighbour directions to the normal.
      const double a = std::atan2(Ny(y, x), Nx(y, x));
      const int k = static_cast<int>(std::lround(a / (std::numbers::pi / 4)));
      const int ox = static_cast<int>(std::lround(std::cos(k * std::numbers::pi / 4)));
      const int oy = static_cast<int>(std::lround(std::sin(k * std::numbers::pi / 4)));
      if (S(y, x) >= S(y + oy, x + ox) && S(y, x) > S(y - oy, x - ox)) {
        weak(y, x) = 255;
        if (S(y, x) >= p.high_threshold) strong(y, x) = 255;
      }
    }
  cv::Mat1b edges = strong.clone();
  for (;;) {
    cv::Mat1b grown;
    cv::dilate(edges, grown, cv::Mat());
    grown &= weak;
    if (cv::countNonZero(grown != edges) == 0) break;
    edges = grown;
  }
  DepthEdges out{edges, cv::Mat1f(size, 0.f), cv::Mat1f(size, 0.f)};
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x)
      if (edges(y, x)) {
        const double normal = std::atan2(Ny(y, x), Nx(y, x));
        double t = normal + std::numbers::pi / 2;
        t = std::fmod(t + 2 * std::numbers::pi, std::numbers::pi);
        out.direction(y, x) = static_cast<float>(t);
        out.shadow(y, x) = static_cast<float>(std::fmod(normal + 2 * std::numbers::pi, 2 * std::numbers::pi));
      }
  return out;
}

struct Rendered {
  MfcRender render;
  DepthEdges edges;
};

// A random bin of the development parts (scenes.hpp, seed `seed`) rendered by the simulated MFC,
// and its depth edges.
Rendered rendered_bin(unsigned seed) {
  const CameraConfig cfg = sim_config();
  MfcRenderer r(cfg);
  const SceneMeshes meshes(r);
  DepthEdgeExtractor extractor(cfg.camera, cfg.flashes);
  Rendered out;
  r.render(random_scene(meshes, seed, false), out.render);
  extractor.extract(out.render.frames, out.edges);
  return out;
}

}  // namespace

TEST(DepthEdges, MatchesReferenceOnRandomImages) {
  CameraConfig cfg = sim_config();
  cfg.camera.image_size = {96, 72};
  cfg.camera.K(0, 2) = 40;
  cfg.camera.K(1, 2) = 30;
  cfg.flashes.positions_mm[3][2] = 25;  // one LED in front of the lens: a finite epipole
  const DepthEdgeParams params;
  DepthEdgeExtractor fast(cfg.camera, cfg.flashes, params);
  std::mt19937 rng(3);
  for (int trial = 0; trial < 20; ++trial) {
    MfcFrames f;
    f.ambient.create(cfg.camera.image_size);
    cv::randu(f.ambient, 0, 40);
    // Smooth random images (blocky, so steps and plateaus occur as in real scenes).
    for (int i = 0; i < 8; ++i) {
      cv::Mat1b small(9, 12), big;
      cv::randu(small, 0, 255);
      cv::resize(small, big, cfg.camera.image_size, 0, 0, trial % 2 ? cv::INTER_NEAREST : cv::INTER_LINEAR);
      f.flash.push_back(big);
    }
    DepthEdges got;
    fast.extract(f, got);
    const DepthEdges want = reference_depth_edges(f, cfg.camera, cfg.flashes, params);
    // Float sums in a different order may flip an exact tie; allow one pixel per image.
    const int differ = cv::countNonZero(got.edges != want.edges);
    EXPECT_LE(differ, 1) << "trial " << trial << " of " << cv::countNonZero(want.edges) << " edge pixels";
    EXPECT_GT(cv::countNonZero(want.edges), 0) << "trial " << trial;
    for (int y = 0; y < got.edges.rows; ++y)
      for (int x = 0; x < got.edges.cols; ++x)
        if (got.edges(y, x) && want.edges(y, x)) {
          EXPECT_LT(undirected_angle_difference(got.direction(y, x), want.direction(y, x)), 1e-4);
          // The shadow side: the same normal, modulo 2 pi.
          EXPECT_LT(oriented_angle_difference(got.shadow(y, x), want.shadow(y, x)), 1e-4);
        }
  }
}

// On simulated bins, depth edges lie within 1 px of the depth discontinuities of the depth
// buffer (jumps above 4 mm, whose shadows are at least ~2 px wide) and find nearly all of them.
TEST(DepthEdges, FindTrueDepthDiscontinuitiesInSimulatedScenes) {
  const CameraConfig cfg = sim_config();
  MfcRenderer r(cfg);
  const SceneMeshes meshes(r);
  DepthEdgeExtractor extractor(cfg.camera, cfg.flashes);
  for (uint32_t seed = 1; seed <= 4; ++seed) {
    MfcRender out;
    r.render(random_scene(meshes, seed, false), out, seed);
    DepthEdges edges;
    extractor.extract(out.frames, edges);
    const cv::Mat1b jumps = depth_discontinuities(out.depth_mm, 4.0f);
    const cv::Mat1b creases = depth_creases(out.depth_mm, cfg.camera.K, 30.f, 4.f);
    const EdgeScore s = score_edges(edges.edges, jumps, 1.0);
    const EdgeScore g = score_edges(edges.edges, jumps | creases, 1.0);
    std::printf(
        "scene %u: %d edge px, %d jump px; vs jumps: precision %.3f recall %.3f; "
        "vs jumps+creases: precision %.3f\n",
        seed, s.detected, s.truth, s.precision, s.recall, g.precision);
    EXPECT_GT(s.truth, 1000);
    // Depth edges also fire on creases next to faces seen at grazing angles (attached
    // shadows), so precision is judged against jumps and creases together.
    EXPECT_GE(g.precision, 0.88) << "scene " << seed;
    EXPECT_GE(s.recall, 0.72) << "scene " << seed;
  }
}

// Painted stripes and checkers are strong intensity edges (Canny finds them) but must not
// become depth edges: inside each part, away from its discontinuities, there are none.
TEST(DepthEdges, PaintedPatternsDoNotAppear) {
  const CameraConfig cfg = sim_config();
  MfcRenderer r(cfg);
  const SceneMeshes meshes(r);
  DepthEdgeExtractor extractor(cfg.camera, cfg.flashes);
  CannyEdgeDetector canny(30, 90);
  for (uint32_t seed = 1; seed <= 3; ++seed) {
    MfcRender out;
    r.render(random_scene(meshes, seed, true), out, seed);
    DepthEdges edges, intensity;
    extractor.extract(out.frames, edges);
    canny.detect(out.frames.flash[0], intensity);
    // Part interiors: part pixels (not the floor) more than 3 px from any depth jump of 1 mm
    // or crease of 30 degrees.
    cv::Mat1b parts = out.part_index > 1, near_jump, interior;
    const cv::Mat1b jumps =
        depth_discontinuities(out.depth_mm, 1.0f) | depth_creases(out.depth_mm, cfg.camera.K, 30.f, 4.f);
    cv::dilate(jumps, near_jump, cv::Mat(), {-1, -1}, 3);
    interior = parts & ~near_jump;
    const int depth_in = cv::countNonZero(edges.edges & interior);
    const int canny_in = cv::countNonZero(intensity.edges & interior);
    std::printf("scene %u: interior %d px, depth edges there %d, Canny edges there %d\n", seed,
                cv::countNonZero(interior), depth_in, canny_in);
    EXPECT_GT(canny_in, 1000) << "the paint should be a visible intensity edge";
    EXPECT_LE(depth_in, canny_in / 50) << "scene " << seed;
  }
}

TEST(DepthEdges, DirectionIsTheTangentOfTheDiscontinuity) {
  const Rendered bin = rendered_bin(5);
  const MfcRender& out = bin.render;
  const DepthEdges& edges = bin.edges;
  // Tangent of the true outline: perpendicular to the gradient of the smoothed
  // foreground mask (parts vs floor).
  cv::Mat1f mask, gx, gy;
  cv::Mat1b fg = out.part_index > 1;
  fg.convertTo(mask, CV_32F, 1.0 / 255);
  cv::GaussianBlur(mask, mask, {0, 0}, 2.0);
  cv::Sobel(mask, gx, CV_32F, 1, 0);
  cv::Sobel(mask, gy, CV_32F, 0, 1);
  int compared = 0, close = 0;
  for (int y = 0; y < mask.rows; ++y)
    for (int x = 0; x < mask.cols; ++x) {
      if (!edges.edges(y, x) || std::hypot(gx(y, x), gy(y, x)) < 0.3) continue;
      const double truth = std::atan2(gy(y, x), gx(y, x)) + std::numbers::pi / 2;
      ++compared;
      close += undirected_angle_difference(edges.direction(y, x), truth) < 20 * std::numbers::pi / 180;
      ASSERT_GE(edges.direction(y, x), 0.f);
      ASSERT_LT(edges.direction(y, x), std::numbers::pi_v<float>);
    }
  EXPECT_GT(compared, 500);
  EXPECT_GE(close, 0.9 * compared) << close << " of " << compared;
}

// The shadow side: the normal DepthEdges::shadow gives points away from the occluder, so the
// rendered depth a few pixels along it is farther than a few pixels against it.
TEST(DepthEdges, ShadowSideIsTheFartherSurface) {
  const Rendered bin = rendered_bin(5);
  const MfcRender& out = bin.render;
  const DepthEdges& edges = bin.edges;
  ASSERT_EQ(edges.shadow.size(), edges.edges.size());
  int compared = 0, right = 0;
  const cv::Rect image(cv::Point(0, 0), out.depth_mm.size());
  for (int y = 0; y < edges.edges.rows; ++y)
    for (int x = 0; x < edges.edges.cols; ++x) {
      if (!edges.edges(y, x)) continue;
      const float a = edges.shadow(y, x);
      ASSERT_GE(a, 0.f);
      ASSERT_LT(a, 2 * std::numbers::pi_v<float>);
      const cv::Point2f n(std::cos(a), std::sin(a));
      const cv::Point behind(cvRound(x + 3 * n.x), cvRound(y + 3 * n.y)),
          before(cvRound(x - 3 * n.x), cvRound(y - 3 * n.y));
      if (!image.contains(behind) || !image.contains(before)) continue;
      const float far = out.depth_mm(behind), near = out.depth_mm(before);
      if (!(far > 0) || !(near > 0) || std::abs(far - near) < 2.f) continue;  // only clear depth jumps
      ++compared;
      right += far > near;
    }
  EXPECT_GT(compared, 500);
  EXPECT_GE(right, 0.95 * compared) << right << " of " << compared;
}

// oriented_tangent keeps the tangent modulo pi and turns it so that its left normal points into
// the shadow.
TEST(DepthEdges, OrientedTangentPointsItsLeftNormalIntoTheShadow) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> tangent(0, std::numbers::pi_v<float>), shadow(0, 2 * std::numbers::pi_v<float>);
  for (int i = 0; i < 1000; ++i) {
    const float t = tangent(rng), s = shadow(rng);
    const float o = oriented_tangent(t, s);
    ASSERT_GE(o, 0.f);
    ASSERT_LT(o, 2 * std::numbers::pi_v<float>);
    ASSERT_LT(undirected_angle_difference(o, t), 1e-5);
    ASSERT_GE(-std::sin(o) * std::cos(s) + std::cos(o) * std::sin(s), -1e-5f) << t << " " << s;
  }
}

TEST(DepthEdges, SteadyStateCallsKeepTheirBuffers) {
  const CameraConfig cfg = sim_config();
  MfcRenderer r(cfg);
  const SceneMeshes meshes(r);
  DepthEdgeExtractor extractor(cfg.camera, cfg.flashes);
  MfcRender out;
  r.render(random_scene(meshes, 1, false), out);
  DepthEdges edges;
  extractor.extract(out.frames, edges);
  const uchar* e = edges.edges.data;
  const uchar* d = edges.direction.data;
  const uchar* sh = edges.shadow.data;
  const uchar* resp = extractor.response().data;
  const cv::Mat1b first = edges.edges.clone();
  extractor.extract(out.frames, edges);
  EXPECT_EQ(edges.edges.data, e);
  EXPECT_EQ(edges.direction.data, d);
  EXPECT_EQ(edges.shadow.data, sh);
  EXPECT_EQ(extractor.response().data, resp);
  EXPECT_EQ(cv::countNonZero(first != edges.edges), 0) << "extraction must be deterministic";
}

TEST(DepthEdges, WrongInputIsNamed) {
  const CameraConfig cfg = sim_config();
  DepthEdgeExtractor extractor(cfg.camera, cfg.flashes);
  MfcFrames f;
  f.ambient = cv::Mat1b(480, 640, uchar(0));
  for (int i = 0; i < 7; ++i) f.flash.push_back(f.ambient);
  DepthEdges out;
  EXPECT_THROW(extractor.extract(f, out), std::invalid_argument);
  f.flash.push_back(cv::Mat1b(240, 320, uchar(0)));
  try {
    extractor.extract(f, out);
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("flash image 7"), std::string::npos) << e.what();
  }
}

TEST(CannyEdges, FindsASquareWithItsDirections) {
  cv::Mat1b img(120, 160, uchar(30));
  cv::rectangle(img, cv::Rect(40, 30, 60, 50), cv::Scalar(200), cv::FILLED);
  CannyEdgeDetector canny(50, 150);
  DepthEdges out;
  canny.detect(img, out);
  int horizontal = 0, vertical = 0;
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      if (!out.edges(y, x)) continue;
      const bool on_side = (std::abs(x - 40) <= 1 || std::abs(x - 99) <= 1) && y > 32 && y < 77;
      const bool on_top = (std::abs(y - 30) <= 1 || std::abs(y - 79) <= 1) && x > 42 && x < 97;
      ASSERT_TRUE(on_side || on_top || (std::abs(x - 40) <= 2 || std::abs(x - 99) <= 2)) << x << "," << y;
      if (on_side) vertical += undirected_angle_difference(out.direction(y, x), std::numbers::pi / 2) < 0.01;
      if (on_top) horizontal += undirected_angle_difference(out.direction(y, x), 0) < 0.01;
    }
  EXPECT_GT(vertical, 80);
  EXPECT_GT(horizontal, 100);
  EXPECT_TRUE(out.shadow.empty()) << "intensity edges do not say which side is nearer";
}
