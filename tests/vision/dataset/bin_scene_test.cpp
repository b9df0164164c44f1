// Simulated bins of the six development parts: placements are deterministic, inside the
// bin, free of interpenetration (checked by ray-parity point-in-mesh tests, independent of
// the height map); ground truth written to a BOP dataset reprojects onto the rendered masks;
// the measured share of removed depth edges is in the requested range and a reader
// measures the same; clutter is real geometry outside the ground truth.
#include "vision/dataset/bin_scene.hpp"
#include "vision/dataset/bop_dataset.hpp"
#include "vision/dataset/resting_poses.hpp"
#include "vision/edges/edge_evaluation.hpp"

#include <gtest/gtest.h>
#include <unistd.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <filesystem>
#include <fstream>
#include <memory>
#include <tuple>
#include <unordered_map>

using namespace mfcd::vision;
namespace fs = std::filesystem;

namespace {

// The simulation camera at half resolution (same field of view): 4x fewer pixels to render.
CameraConfig test_camera() {
  CameraConfig c = load_camera_config(MFC_SOURCE_DIR "/config/camera-sim.yaml");
  c.camera.image_size = {320, 240};
  c.camera.K = cv::Matx33d(550, 0, 159.5, 0, 550, 119.5, 0, 0, 1);
  return c;
}

std::vector<PartModel> development_parts() {
  std::vector<PartModel> models;
  int id = 1;
  for (const char* name : {"breaker", "diamond", "ellipse", "tnut", "knob", "wheel"}) {
    const fs::path stl = fs::path(MFC_BINARY_DIR) / "parts" / (std::string(name) + ".stl");
    if (!fs::exists(stl)) return {};
    PartModel m;
    m.obj_id = id++;
    m.name = name;
    m.mesh = load_mesh(stl);
    models.push_back(std::move(m));
  }
  return models;
}

// Odd direction so rays do not run along mesh edges or faces.
bool inside(const Mesh& m, const cv::Vec3d& p) {
  const cv::Vec3d d = cv::normalize(cv::Vec3d(0.5377, 0.2771, 0.7963));
  int hits = 0;
  for (const auto& t : m.triangles) {
    const cv::Vec3d a = m.vertices[t[0]], b = m.vertices[t[1]], c = m.vertices[t[2]];
    const cv::Vec3d e1 = b - a, e2 = c - a, h = d.cross(e2);
    const double det = e1.dot(h);
    if (std::abs(det) < 1e-12) continue;
    const cv::Vec3d s = p - a;
    const double u = s.dot(h) / det;
    if (u < 0 || u > 1) continue;
    const cv::Vec3d q = s.cross(e1);
    const double v = d.dot(q) / det;
    if (v < 0 || u + v > 1) continue;
    hits += e2.dot(q) / det > 0;
  }
  return hits % 2 == 1;
}

// A point w (camera frame) deeper than ~0.5 mm inside the mesh placed at (R, t): the point and its
// six neighbours 0.5 mm away are all inside. Shallower contact is the drop's clearance at work.
bool deep_inside(const Mesh& m, const cv::Matx33d& R, const cv::Vec3d& t, const cv::Vec3d& w) {
  const cv::Matx33d Rt = R.t();
  if (!inside(m, Rt * (w - t))) return false;
  for (int k = 0; k < 6; ++k) {
    cv::Vec3d off(0, 0, 0);
    off[k / 2] = k % 2 ? 0.5 : -0.5;
    if (!inside(m, Rt * (w + off - t))) return false;
  }
  return true;
}

// Points on the surface: vertices plus samples every ~1.5 mm over every triangle.
std::vector<cv::Vec3d> surface_points(const Mesh& m) {
  std::vector<cv::Vec3d> pts;
  for (const auto& t : m.triangles) {
    const cv::Vec3d a = m.vertices[t[0]], b = m.vertices[t[1]], c = m.vertices[t[2]];
    const int n = 1 + static_cast<int>(std::max({cv::norm(b - a), cv::norm(c - a), cv::norm(c - b)}) / 1.5);
    for (int i = 0; i <= n; ++i)
      for (int j = 0; i + j <= n; ++j) pts.push_back(a + (b - a) * (double(i) / n) + (c - a) * (double(j) / n));
  }
  return pts;
}

struct Shared {
  std::unique_ptr<BinSimulator> sim;
  SimulatedImage image;
  fs::path root;
};

class BinScenes : public testing::Test {
 protected:
  static void SetUpTestSuite() {
    auto models = development_parts();
    if (models.empty()) return;
    BinSceneOptions opt;
    opt.parts_per_image = 6;
    shared_ = new Shared;
    shared_->sim = std::make_unique<BinSimulator>(test_camera(), std::move(models), opt);
  }
  static void TearDownTestSuite() {
    if (shared_ && !shared_->root.empty()) fs::remove_all(shared_->root);
    delete shared_;
    shared_ = nullptr;
  }
  void SetUp() override {
    if (!shared_) GTEST_SKIP() << "development parts not built (" << MFC_BINARY_DIR << "/parts/*.stl need openscad)";
  }
  BinSimulator& sim() { return *shared_->sim; }
  // One simulated image, written as a one-image dataset; made once per test process.
  const SimulatedImage& image() {
    if (shared_->root.empty()) {
      shared_->image = sim().simulate(21);
      shared_->root = fs::temp_directory_path() / ("mfcd_bins_" + std::to_string(::getpid()));
      BopWriter w(shared_->root);
      w.write_models(sim().models());
      w.write_scene(1, sim().camera(), {shared_->image});
    }
    return shared_->image;
  }
  const fs::path& root() {
    image();
    return shared_->root;
  }
  static Shared* shared_;
};
Shared* BinScenes::shared_ = nullptr;

}  // namespace

TEST_F(BinScenes, LayoutIsDeterministicInTheSeed) {
  const BinLayout a = sim().layout(5), b = sim().layout(5), c = sim().layout(6);
  ASSERT_EQ(a.parts.size(), b.parts.size());
  ASSERT_EQ(a.clutter.size(), b.clutter.size());
  for (size_t k = 0; k < a.parts.size(); ++k) {
    EXPECT_EQ(a.parts[k].model, b.parts[k].model);
    EXPECT_EQ(a.parts[k].R, b.parts[k].R);
    EXPECT_EQ(a.parts[k].t_mm, b.parts[k].t_mm);
  }
  EXPECT_NE(a.parts[0].t_mm, c.parts[0].t_mm);
}

TEST_F(BinScenes, PartsRestInsideTheBinWithoutInterpenetrating) {
  const BinGeometry& bin = sim().options().bin;
  const double floor_z = sim().camera().working_distance_mm;
  for (uint64_t seed = 1; seed <= 2; ++seed) {
    const BinLayout layout = sim().layout(seed);
    EXPECT_EQ(layout.parts.size(), 6u) << "seed " << seed;
    struct Placed {
      const Mesh* mesh;
      cv::Matx33d R;
      cv::Vec3d t;
      std::vector<cv::Vec3d> world;  // surface samples in the camera frame
      cv::Vec3d lo, hi;
    };
    std::vector<Placed> objs;
    for (const auto& p : layout.parts)
      objs.push_back({&sim().models()[static_cast<size_t>(p.model)].mesh, p.R, p.t_mm, {}, {}, {}});
    for (const auto& c : layout.clutter) objs.push_back({&sim().rod_mesh(c.rod), c.R, c.t_mm, {}, {}, {}});
    for (auto& o : objs) {
      o.lo = cv::Vec3d(1e9, 1e9, 1e9);
      o.hi = -o.lo;
      for (const auto& q : surface_points(*o.mesh)) {
        const cv::Vec3d w = o.R * q + o.t;
        o.world.push_back(w);
        for (int k = 0; k < 3; ++k) {
          o.lo[k] = std::min(o.lo[k], w[k]);
          o.hi[k] = std::max(o.hi[k], w[k]);
        }
      }
      // Inside the walls, on or above the floor, not above the wall tops.
      EXPECT_GE(o.lo[0], -bin.inner_x_mm / 2 - 1e-6);
      EXPECT_LE(o.hi[0], bin.inner_x_mm / 2 + 1e-6);
      EXPECT_GE(o.lo[1], -bin.inner_y_mm / 2 - 1e-6);
      EXPECT_LE(o.hi[1], bin.inner_y_mm / 2 + 1e-6);
      EXPECT_LE(o.hi[2], floor_z + 1e-3) << "below the floor";
      EXPECT_GE(o.lo[2], floor_z - bin.wall_height_mm - 1e-6) << "sticks out of the bin";
    }
    // Surface samples hashed into 2.5 mm voxels: contact search looks at 27 voxels only.
    auto cell_of = [](const cv::Vec3d& w) {
      return std::tuple{static_cast<int64_t>(std::floor(w[0] / 2.5)), static_cast<int64_t>(std::floor(w[1] / 2.5)),
                        static_cast<int64_t>(std::floor(w[2] / 2.5))};
    };
    auto key = [](int64_t x, int64_t y, int64_t z) {
      return (x + (1 << 20)) << 42 | (y + (1 << 20)) << 21 | (z + (1 << 20));
    };
    std::unordered_map<int64_t, std::vector<std::pair<size_t, cv::Vec3d>>> grid;
    for (size_t b = 0; b < objs.size(); ++b)
      for (const auto& w : objs[b].world) {
        const auto [x, y, z] = cell_of(w);
        grid[key(x, y, z)].emplace_back(b, w);
      }
    for (size_t a = 0; a < objs.size(); ++a) {
      // At rest: the lowest surface points (the support face lies flat) that touch the
      // floor or another object (within the drop clearance, contact tolerance and sample
      // spacing) surround the centre of mass.
      std::vector<cv::Point2f> contacts;
      for (const auto& w : objs[a].world) {
        if (w[2] < objs[a].hi[2] - 0.05) continue;
        bool touches = floor_z - w[2] < 0.05;
        const auto [ix, iy, iz] = cell_of(w);
        for (int d = 0; d < 27 && !touches; ++d) {
          const auto it = grid.find(key(ix + d % 3 - 1, iy + d / 3 % 3 - 1, iz + d / 9 - 1));
          if (it == grid.end()) continue;
          for (const auto& [b, o] : it->second) touches |= b != a && cv::norm(o - w) < 2.5;
        }
        if (touches) contacts.emplace_back(static_cast<float>(w[0]), static_cast<float>(w[1]));
      }
      ASSERT_GE(contacts.size(), 3u) << "seed " << seed << " object " << a << " floats";
      std::vector<cv::Point2f> hull;
      cv::convexHull(contacts, hull);
      const cv::Vec3d com = objs[a].R * centre_of_mass(*objs[a].mesh) + objs[a].t;
      EXPECT_GE(cv::pointPolygonTest(hull, cv::Point2f(static_cast<float>(com[0]), static_cast<float>(com[1])), true),
                -1.0)
          << "seed " << seed << " object " << a << " would tip over";
      for (size_t b = 0; b < objs.size(); ++b) {
        if (a == b) continue;
        // Surface points of a deeper than ~0.5 mm inside b count as interpenetration.
        int deep = 0;
        for (const auto& w : objs[a].world) {
          if (w[0] < objs[b].lo[0] || w[0] > objs[b].hi[0] || w[1] < objs[b].lo[1] || w[1] > objs[b].hi[1] ||
              w[2] < objs[b].lo[2] || w[2] > objs[b].hi[2])
            continue;
          deep += deep_inside(*objs[b].mesh, objs[b].R, objs[b].t, w);
        }
        EXPECT_EQ(deep, 0) << "seed " << seed << ": object " << a << " inside object " << b;
      }
    }
  }
}

TEST_F(BinScenes, GroundTruthReprojectsOntoTheRenderedMasks) {
  const BopDataset ds(root());
  const BopSceneCamera cam = ds.camera(1, 0);
  const auto gt = ds.ground_truth(1, 0);
  const auto info = ds.ground_truth_info(1, 0);
  ASSERT_EQ(gt.size(), image().instances.size());
  ASSERT_GE(gt.size(), 4u);
  for (size_t g = 0; g < gt.size(); ++g) {
    // Software rasterisation of the model PLY at the stored pose with the stored K.
    const Mesh model = load_mesh(ds.model_path(gt[g].obj_id));
    PinholeCamera pin;
    pin.K = cam.K;
    cv::Mat1b drawn(cam.image_size, 0);
    for (const auto& t : model.triangles) {
      std::vector<cv::Point> poly;
      for (uint32_t v : t) {
        const cv::Point2d p = pin.project(gt[g].R * cv::Vec3d(model.vertices[v]) + gt[g].t_mm);
        poly.emplace_back(static_cast<int>(std::lround(p.x * 16)), static_cast<int>(std::lround(p.y * 16)));
      }
      cv::fillConvexPoly(drawn, poly, 255, cv::LINE_8, 4);
    }
    char name[64];
    std::snprintf(name, sizeof name, "000000_%06zu.png", g);
    const cv::Mat1b all = cv::imread((ds.scene_dir(1) / "mask" / name).string(), cv::IMREAD_UNCHANGED);
    const cv::Mat1b visib = ds.mask_visib(1, 0, static_cast<int>(g));
    // Every silhouette pixel within a pixel of the drawn model and vice versa (edge
    // pixels may differ: GL covers pixel centres, fillConvexPoly its boundary too).
    cv::Mat1b near_drawn, near_all;
    cv::dilate(drawn, near_drawn, cv::Mat());
    cv::dilate(all, near_all, cv::Mat());
    ASSERT_GT(cv::countNonZero(all), 100);
    EXPECT_LE(cv::countNonZero(all & ~near_drawn), cv::countNonZero(all) / 200) << "instance " << g;
    EXPECT_LE(cv::countNonZero(drawn & ~near_all), cv::countNonZero(drawn) / 200) << "instance " << g;
    EXPECT_EQ(cv::countNonZero(visib & ~all), 0) << "visible pixels outside the silhouette";
    // Whole silhouettes (BOP): more than the image holds only for a part cut by its border.
    const bool cut = cv::countNonZero(all.row(0)) || cv::countNonZero(all.row(all.rows - 1)) ||
                     cv::countNonZero(all.col(0)) || cv::countNonZero(all.col(all.cols - 1));
    if (cut) {
      EXPECT_GE(info[g].px_count_all, cv::countNonZero(all));
    } else {
      EXPECT_EQ(info[g].px_count_all, cv::countNonZero(all));
      EXPECT_EQ(info[g].bbox_obj, cv::boundingRect(all));
    }
    EXPECT_EQ(info[g].px_count_visib, cv::countNonZero(visib));
    EXPECT_NEAR(info[g].visib_fract, double(cv::countNonZero(visib)) / info[g].px_count_all, 1e-12);
  }
}

// BOP's visib_fract is of the whole silhouette: a part the image border cuts in half is half
// hidden, even with nothing over it (bop_toolkit's calc_gt_info renders on a canvas three times
// the image's size). Moved so that its centre lies on the left border, the part's image
// silhouette is about half its whole one and the box starts left of the image.
TEST_F(BinScenes, APartCutByTheImageBorderCountsAsPartlyHidden) {
  BinSceneOptions opt = sim().options();
  opt.parts_per_image = 1;
  opt.clutter.enabled = false;
  opt.missing.enabled = false;
  BinSimulator one(sim().camera(), sim().models(), opt);
  BinLayout layout = one.layout(5);
  ASSERT_EQ(layout.parts.size(), 1u);
  const SimulatedImage inside = one.simulate(layout, 5);
  ASSERT_EQ(inside.instances.size(), 1u);
  const PartInstance& a = inside.instances[0];
  EXPECT_EQ(a.px_count_all, cv::countNonZero(a.mask_all));
  EXPECT_GT(a.visib_fract, 0.99);

  // Shift the part sideways until the projection of its position is on the image's left edge.
  const PinholeCamera& cam = one.camera().camera;
  PlacedObject& p = layout.parts[0];
  const cv::Point2d at = cam.project(p.t_mm);
  p.t_mm[0] -= at.x * p.t_mm[2] / cam.K(0, 0);
  const SimulatedImage cut = one.simulate(layout, 5);
  const PartInstance& b = cut.instances[0];
  const int in_image = cv::countNonZero(b.mask_all);
  EXPECT_GT(b.px_count_all, in_image);
  EXPECT_NEAR(b.px_count_all, a.px_count_all, 0.1 * a.px_count_all) << "the same part at the same depth";
  EXPECT_NEAR(b.visib_fract, double(cv::countNonZero(b.mask_visib)) / b.px_count_all, 1e-12);
  EXPECT_LT(b.visib_fract, 0.8);
  EXPECT_GT(b.visib_fract, 0.2);
  EXPECT_LT(b.bbox_obj.x, 0);
  EXPECT_GT(b.bbox_obj.width, cv::boundingRect(b.mask_all).width);
}

TEST_F(BinScenes, RemovedDepthEdgesAreInTheRequestedRangeAndReproducible) {
  const CorruptionReport& c = image().corruption;
  const double want = sim().options().missing.fraction;
  EXPECT_GE(c.removed_fraction, want - 0.03);
  EXPECT_LE(c.removed_fraction, want + 0.05);
  EXPECT_GT(c.stretches, 0);
  EXPECT_GT(c.recall_clean, 0.8);
  // Removing edges must not draw new ones: a stretch that lifted a wide cast shadow only over
  // its disc moved the shadow's step to the disc's rim (5.5 % of the clean edge pixels added
  // on the capped-occlusion bins at full resolution, 2.8 % on this half-resolution image, before
  // each flash's shadow was swept too; 0.8 % and 1.3 % after).
  EXPECT_LT(c.added_fraction, 0.02) << "edges drawn by the removal";
  // A reader measuring on the stored images and depth finds the same share.
  const BopDataset ds(root());
  const CameraConfig cfg = ds.camera(1, 0).config();
  DepthEdgeExtractor extractor(cfg.camera, cfg.flashes);
  DepthEdges edges;
  extractor.extract(ds.frames(1, 0), edges);
  const cv::Mat1b truth = depth_discontinuities(ds.depth_mm(1, 0), sim().options().edge_min_jump_mm);
  const EdgeScore s = score_edges(edges.edges, truth, sim().options().edge_tolerance_px);
  EXPECT_NEAR(s.recall, c.recall_corrupted, 0.01);
  const auto stored = nlohmann::json::parse(std::ifstream(ds.scene_dir(1) / "scene_mfc_corruption.json"));
  EXPECT_DOUBLE_EQ(stored["0"]["removed_fraction"].get<double>(), c.removed_fraction);
  EXPECT_DOUBLE_EQ(stored["0"]["added_fraction"].get<double>(), c.added_fraction);
}

TEST_F(BinScenes, ClutterRodsAreDepthEdgesButNotGroundTruth) {
  const SimulatedImage& im = image();
  const ClutterOptions& co = sim().options().clutter;
  EXPECT_GE(static_cast<int>(im.layout.clutter.size()), co.min_rods);
  EXPECT_LE(static_cast<int>(im.layout.clutter.size()), co.max_rods);
  EXPECT_EQ(im.instances.size(), im.layout.parts.size());
  // Rod pixels of the scene's visibility map, and depth edges detected along them.
  cv::Mat1f depth;
  cv::Mat1b index;
  sim().renderer().render_depth(sim().scene_parts(im.layout), depth, index);
  const int first_rod = BinSimulator::first_part_index() + static_cast<int>(im.layout.parts.size());
  const cv::Mat1b rods = index >= first_rod;
  cv::Mat1b rod_outline;
  cv::morphologyEx(rods, rod_outline, cv::MORPH_GRADIENT, cv::Mat());
  DepthEdges edges;
  DepthEdgeExtractor(sim().camera().camera, sim().camera().flashes).extract(im.frames, edges);
  EXPECT_GT(cv::countNonZero(rods), 200);
  EXPECT_GT(cv::countNonZero(edges.edges & rod_outline), 40 * static_cast<int>(im.layout.clutter.size()) / 4)
      << "rods leave few depth edges";
}

TEST_F(BinScenes, OcclusionLimitIsRespected) {
  // Without a limit this bin has heavily occluded parts ...
  double worst = 0;
  for (const auto& inst : image().instances) worst = std::max(worst, 1 - inst.visib_fract);
  EXPECT_GT(worst, 0.3);
  // ... with one, every part (and every clutter rod over it) keeps 85 % of its pixels.
  BinSceneOptions opt = sim().options();
  opt.max_occlusion = 0.15;
  opt.parts_per_image = 4;
  opt.missing.enabled = false;
  BinSimulator limited(sim().camera(), sim().models(), opt);
  const SimulatedImage im = limited.simulate(3);
  EXPECT_EQ(im.instances.size(), 4u);
  for (const auto& inst : im.instances) EXPECT_GE(inst.visib_fract, 0.85 - 1e-12);
  EXPECT_EQ(im.corruption.stretches, 0);
  EXPECT_EQ(im.corruption.removed_fraction, 0);
}

// A drop picks the resting face by support area (the default) or by solid angle at the centre
// of mass: dropped alone, the diamond lands on its rim (4 side faces, stable_resting_poses) as
// often as those weights say, within 3 standard deviations of 300 drops.
TEST_F(BinScenes, RestingFacesAreDrawnByTheChosenWeight) {
  std::vector<PartModel> diamond;
  for (const auto& m : sim().models())
    if (m.name == "diamond") diamond.push_back(m);
  ASSERT_EQ(diamond.size(), 1u);
  const auto poses = stable_resting_poses(diamond[0].mesh);
  double area = 0, area_rim = 0, solid = 0, solid_rim = 0;
  for (const auto& p : poses) {
    const bool rim = std::abs(p.face_normal[2]) < 0.1;
    area += p.support_area_mm2, solid += p.solid_angle_sr;
    if (rim) area_rim += p.support_area_mm2, solid_rim += p.solid_angle_sr;
  }
  BinSceneOptions opt = sim().options();
  opt.parts_per_image = 1;
  opt.clutter.enabled = false;
  const int drops = 300;
  for (const auto weight :
       {BinSceneOptions::RestingWeight::support_area, BinSceneOptions::RestingWeight::solid_angle}) {
    opt.resting_weight = weight;
    BinSimulator alone(sim().camera(), diamond, opt);
    int on_rim = 0, placed = 0;
    for (int seed = 0; seed < drops; ++seed) {
      const BinLayout layout = alone.layout(static_cast<uint64_t>(1000 + seed));
      if (layout.parts.empty()) continue;
      ++placed;
      // The model's z axis (the plate normal) is horizontal when the plate stands on its rim.
      on_rim += std::abs(layout.parts[0].R(2, 2)) < 0.2;
    }
    const double expected =
        weight == BinSceneOptions::RestingWeight::support_area ? area_rim / area : solid_rim / solid;
    const double share = double(on_rim) / placed;
    std::printf("%s: %d of %d on the rim (%.3f, expected %.3f)\n",
                weight == BinSceneOptions::RestingWeight::support_area ? "support area" : "solid angle", on_rim, placed,
                share, expected);
    EXPECT_EQ(placed, drops);
    EXPECT_NEAR(share, expected, 3 * std::sqrt(expected * (1 - expected) / drops));
  }
  EXPECT_LT(solid_rim / solid, area_rim / area - 0.1);
}

// Leaning parts (BinSceneOptions::max_lean_deg): every part's orientation is one of its resting
// poses tilted by at most the limit, a good share are tilted by more than a few degrees (they
// rest on the parts below), and none sinks into the floor or into another object.
TEST_F(BinScenes, LeaningPartsTiltWithinTheLimitWithoutInterpenetrating) {
  BinSceneOptions opt = sim().options();
  opt.max_lean_deg = 30;
  BinSimulator leaning(sim().camera(), sim().models(), opt);
  const double floor_z = sim().camera().working_distance_mm;
  std::vector<std::vector<RestingPose>> poses;
  for (const auto& m : sim().models()) poses.push_back(stable_resting_poses(m.mesh));
  int parts = 0, tilted = 0;
  for (uint64_t seed = 1; seed <= 6; ++seed) {
    const BinLayout layout = leaning.layout(seed);
    struct Placed {
      const Mesh* mesh;
      cv::Matx33d R;
      cv::Vec3d t;
    };
    std::vector<Placed> objs;
    for (const auto& p : layout.parts) {
      const auto& rest = poses[static_cast<size_t>(p.model)];
      // Gravity (camera +z) in the part's frame is the support face's outward normal at rest.
      const cv::Vec3d down = p.R.t() * cv::Vec3d(0, 0, 1);
      double tilt = 180;
      for (const auto& r : rest)
        tilt = std::min(tilt, std::acos(std::clamp(down.dot(r.face_normal), -1.0, 1.0)) * 180 / CV_PI);
      EXPECT_LE(tilt, 30 + 1e-6) << "seed " << seed;
      ++parts;
      tilted += tilt > 5;
      objs.push_back({&sim().models()[static_cast<size_t>(p.model)].mesh, p.R, p.t_mm});
    }
    for (const auto& c : layout.clutter) objs.push_back({&sim().rod_mesh(c.rod), c.R, c.t_mm});
    for (size_t a = 0; a < objs.size(); ++a) {
      for (const auto& v : objs[a].mesh->vertices)
        EXPECT_LE((objs[a].R * cv::Vec3d(v) + objs[a].t)[2], floor_z + 1e-3) << "seed " << seed << ": below the floor";
      for (size_t b = 0; b < objs.size(); ++b) {
        if (a == b) continue;
        // Vertices of a deeper than ~0.5 mm inside b count as interpenetration.
        int deep = 0;
        for (const auto& v : objs[a].mesh->vertices)
          deep += deep_inside(*objs[b].mesh, objs[b].R, objs[b].t, objs[a].R * cv::Vec3d(v) + objs[a].t);
        EXPECT_EQ(deep, 0) << "seed " << seed << ": object " << a << " inside object " << b;
      }
    }
  }
  std::printf("%d of %d parts tilted more than 5 degrees from every resting pose\n", tilted, parts);
  EXPECT_GE(parts, 30);
  EXPECT_GE(tilted, parts / 5);

  for (const double bad : {-1.0, 90.0}) {
    opt.max_lean_deg = bad;
    EXPECT_THROW(BinSimulator(sim().camera(), sim().models(), opt), std::invalid_argument) << bad;
  }
}
