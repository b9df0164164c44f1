// The whole pick-cycle vision path on rendered multi-flash scenes of the development parts:
// each part, alone on a floor in a pose between template views (up to 4 degrees off any view),
// is found with the right part type and a coarse pose within the paper's correctness bounds
// (5 mm, 10 degrees, symmetry-aware).
#include "tests/hal/alloc_counter.hpp"
#include "tests/vision/support/floor_scene.hpp"
#include "tests/vision/support/pose_errors.hpp"
#include "tests/vision/support/rim_diamonds.hpp"
#include "vision/pipeline/bin_picking_pipeline.hpp"
#include "vision/pose/coarse_pose.hpp"
#include "vision/render/mfc_renderer.hpp"
#include "vision/templates/template_database.hpp"

#include <gtest/gtest.h>

#include <omp.h>
#include <array>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <random>
#include <tuple>

using namespace mfcd::vision;
namespace fs = std::filesystem;

namespace {

const fs::path kTemplates = fs::path(MFC_BINARY_DIR) / "templates";

CameraConfig sim_camera() { return load_camera_config(fs::path(MFC_SOURCE_DIR) / "config/camera-sim.yaml"); }

using mfcd::vision::testing::rotation_error_deg;

using mfcd::vision::testing::render_on_floor;

// The coarse pose of the first template view that sees the part from well above, placed at
// `origin` turned by `angle` in the image.
RigidPose upper_view_pose(const TemplateDatabase& db, const CameraConfig& cam, double angle, cv::Point2d origin) {
  int view = 0;
  while (db.views[view].view_direction[2] < 0.5) ++view;
  return coarse_pose(db, TemplatePlacement{view, angle, 1.0, origin}, cam.camera);
}

// One part at an upper view's pose, rendered over a floor: the scene of the single-part tests.
struct RenderedPart {
  TemplateDatabase db;
  RigidPose truth;
  cv::Vec3d centre;  // the truth's part centre, camera frame
  MfcRender render;
};

RenderedPart render_part(const fs::path& tdb, const CameraConfig& cam, double angle, cv::Point2d origin,
                         uint64_t seed) {
  RenderedPart out;
  out.db = load_template_database(tdb);
  out.truth = upper_view_pose(out.db, cam, angle, origin);
  out.centre = out.truth.R * out.db.center_mm + out.truth.t_mm;
  MfcRenderer renderer(cam);
  const int part_id = renderer.add_mesh(out.db.mesh);
  const int floor_id = renderer.add_mesh(make_plane(600));
  out.render = render_on_floor(renderer, part_id, floor_id, out.db, out.truth, seed);
  return out;
}

// The six development parts side by side on a floor, two rows of three 150 px apart (their
// outlines come close, as in a bin), each at an upper view's pose; the files of their templates.
struct SixParts {
  std::vector<fs::path> files;
  MfcRender render;
};

SixParts render_six_parts(const CameraConfig& cam) {
  const std::vector<std::string> names = {"breaker", "diamond", "ellipse", "tnut", "knob", "wheel"};
  MfcRenderer renderer(cam);
  SixParts out;
  std::vector<ScenePart> scene;
  double floor_mm = 0;
  for (size_t k = 0; k < names.size(); ++k) {
    out.files.push_back(kTemplates / (names[k] + ".tdb"));
    const TemplateDatabase db = load_template_database(out.files.back());
    const cv::Point2d at(170 + 150 * double(k % 3), 170 + 140 * double(k / 3));
    const RigidPose pose = upper_view_pose(db, cam, 0.9 * double(k) + 0.3, at);
    scene.push_back({renderer.add_mesh(db.mesh), pose.R, pose.t_mm, Material::matte(0.6f)});
    floor_mm = std::max(floor_mm, (pose.R * db.center_mm + pose.t_mm)[2] + db.diameter_mm / 2 + 10);
  }
  scene.push_back({renderer.add_mesh(make_plane(600)), cv::Matx33d::eye(), {0, 0, floor_mm}, Material::matte(0.5f)});
  renderer.render(scene, out.render, 11);
  return out;
}

// The Table 1 criterion: centre within 5 mm, rotation within 10 degrees (symmetry-aware).
void expect_within_bounds(const PoseCandidate& c, const RenderedPart& scene) {
  EXPECT_LE(cv::norm(c.R_m2c * scene.db.center_mm + c.t_m2c_mm - scene.centre), 5.0);
  EXPECT_LE(rotation_error_deg(c.R_m2c, scene.truth.R, scene.db.symmetry), 10.0);
}

// Distance from the camera (along the optical axis) of the model's deepest vertex at `pose`.
double deepest_mm(const Mesh& mesh, const RigidPose& pose) {
  double z = -1e9;
  for (const cv::Vec3f& p : mesh.vertices) z = std::max(z, (pose.R * cv::Vec3d(p[0], p[1], p[2]) + pose.t_mm)[2]);
  return z;
}

// One cycle of a pipeline made with `pc` on `frames`, every part type, a generous deadline.
PipelineResult process_once(const CameraConfig& cam, const PipelineConfig& pc, const MfcFrames& frames) {
  BinPickingPipeline pipeline(cam, pc);
  PipelineResult r;
  pipeline.process(frames, 0, std::chrono::steady_clock::now() + std::chrono::seconds(60), r);
  return r;
}

// A pose between template views: `view`'s coarse pose at the template distance, turned in the
// image at random and shifted from the image centre by up to `spread` px, then tilted about the
// part centre by up to 4 degrees.
RigidPose pose_between_views(const TemplateDatabase& db, const CameraConfig& cam, int view, cv::Point2d spread,
                             std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  TemplatePlacement pl{view, u(rng) * CV_PI, 1.0, {320 + spread.x * u(rng), 240 + spread.y * u(rng)}};
  RigidPose pose = coarse_pose(db, pl, cam.camera);
  cv::Matx33d tilt;
  cv::Rodrigues(cv::Vec3d(u(rng), u(rng), u(rng)) * (4 * CV_PI / 180 / std::sqrt(3.0)), tilt);
  const cv::Vec3d centre = pose.R * db.center_mm + pose.t_mm;
  pose.R = tilt * pose.R;
  pose.t_mm = centre - pose.R * db.center_mm;
  return pose;
}

struct SceneCase {
  const char* part;
};

// (part, PipelineConfig::search_downsample): the default reduced search and the full-resolution one.
class PipelineOnRenderedPart : public ::testing::TestWithParam<std::tuple<const char*, int>> {
 protected:
  const char* part() const { return std::get<0>(GetParam()); }
  int downsample() const { return std::get<1>(GetParam()); }
};

using mfcd::vision::testing::RimDiamonds;

}  // namespace

TEST_P(PipelineOnRenderedPart, FindsThePartWithinFiveMillimetresAndTenDegrees) {
  const fs::path tdb = kTemplates / (std::string(part()) + ".tdb");
  ASSERT_TRUE(fs::exists(tdb)) << tdb;
  const TemplateDatabase db = load_template_database(tdb);
  const CameraConfig cam = sim_camera();
  PipelineConfig pc;
  pc.template_files = {tdb};
  pc.search_downsample = downsample();
  BinPickingPipeline pipeline(cam, pc);

  MfcRenderer renderer(cam);
  const int part_id = renderer.add_mesh(db.mesh);
  const int floor_id = renderer.add_mesh(make_plane(600));
  std::mt19937 rng(std::hash<std::string>{}(part()) % 1000);
  int found = 0, trials = 3;
  for (int trial = 0; trial < trials; ++trial) {
    // A pose between template views: a random view, tilted by up to 4 degrees, turned in plane,
    // shifted in the image, at the template distance.
    // Views of the part's upper side: from below, the breaker shows only its 2-fold symmetric
    // base and no image can tell its two 180-degree turns apart (docs/pose.md); the evaluation
    // (mfc-eval) measures all resting poses.
    int view = 0;
    do view = std::uniform_int_distribution<int>(0, static_cast<int>(db.views.size()) - 1)(rng);
    while (db.views[view].view_direction[2] < 0.2);
    const RigidPose truth = pose_between_views(db, cam, view, {150, 100}, rng);
    const cv::Vec3d centre = truth.R * db.center_mm + truth.t_mm;
    const MfcRender render = render_on_floor(renderer, part_id, floor_id, db, truth, 100 + trial);
    PipelineResult result;
    pipeline.process(render.frames, 0, std::chrono::steady_clock::now() + std::chrono::seconds(30), result);
    if (const char* dir = std::getenv("MFC_TEST_DUMP"))
      cv::imwrite(std::string(dir) + "/" + part() + "-" + std::to_string(trial) + "-edges.png",
                  pipeline.last_edges().edges);
    ASSERT_FALSE(result.candidates.empty())
        << result.edge_pixels << " edge pixels, " << result.query_lines << " query lines, " << result.hypotheses
        << " hypotheses; true view " << view;
    const PoseCandidate& best = result.candidates.front();
    const cv::Vec3d found_centre = best.R_m2c * db.center_mm + best.t_m2c_mm;
    const double dt = cv::norm(found_centre - centre);
    const double dr = rotation_error_deg(best.R_m2c, truth.R, db.symmetry);
    std::printf(
        "%s trial %d: view %d -> %d, cost %.2f px, centre error %.2f mm, rotation error %.2f deg, %.1f ms "
        "(edges %.1f lines %.1f dt %.1f search %.1f refine %.1f, %.2f M hypotheses)\n",
        part(), trial, view, best.view, best.cost_px, dt, dr, result.times.total_ms, result.times.edges_ms,
        result.times.lines_ms, result.times.distance_ms, result.times.search_ms, result.times.refine_ms,
        result.hypotheses * 1e-6);
    found += dt <= 5 && dr <= 10;
    // The truth scored where it is (PoseScore::exact_score, the fitted rank's measure unfitted)
    // beats the same pose moved 10 mm sideways, where its edges are not.
    const PoseScore at_truth = pipeline.score_pose(db.obj_id, truth.R, truth.t_mm);
    const PoseScore beside = pipeline.score_pose(db.obj_id, truth.R, truth.t_mm + cv::Vec3d(10, 0, 0));
    std::printf("%s trial %d: exact score %.3f at the truth, %.3f 10 mm beside, best candidate %.3f\n", part(), trial,
                at_truth.exact_score, beside.exact_score, best.score);
    EXPECT_GT(at_truth.exact_score, beside.exact_score + 0.2);
  }
  EXPECT_EQ(found, trials);
}

INSTANTIATE_TEST_SUITE_P(Parts, PipelineOnRenderedPart,
                         ::testing::Combine(::testing::Values("breaker", "diamond", "ellipse", "tnut", "knob", "wheel"),
                                            ::testing::Values(3, 1)));

TEST(Pipeline, RefusesBadConfiguration) {
  const CameraConfig cam = sim_camera();
  PipelineConfig pc;
  EXPECT_THROW(BinPickingPipeline(cam, pc), std::runtime_error);
  pc.template_files = {kTemplates / "no-such.tdb"};
  EXPECT_THROW(BinPickingPipeline(cam, pc), std::runtime_error);
  pc.template_files = {kTemplates / "tnut.tdb", kTemplates / "tnut.tdb"};
  try {
    BinPickingPipeline p(cam, pc);
    ADD_FAILURE() << "two databases with one obj_id accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("obj_id"), std::string::npos) << e.what();
  }
  CameraConfig other = cam;
  other.camera.K(0, 0) = 900;
  pc.template_files = {kTemplates / "tnut.tdb"};
  EXPECT_THROW(BinPickingPipeline(other, pc), std::runtime_error);
  pc.evidence_weight = -0.1;
  try {
    BinPickingPipeline p(cam, pc);
    ADD_FAILURE() << "negative evidence_weight accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("evidence_weight"), std::string::npos) << e.what();
  }
  pc.evidence_weight = 0.06;
  pc.floor.distance_mm = 300;
  pc.floor.normal = {0, 0, 2};
  try {
    BinPickingPipeline p(cam, pc);
    ADD_FAILURE() << "a floor normal of length 2 accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("normal"), std::string::npos) << e.what();
  }
  pc.floor = {};
  // A setting out of its range is refused naming it; the setting is restored after.
  auto refuses = [&]<class T>(const char* name, T PipelineConfig::*field, std::initializer_list<T> bad) {
    const T good = pc.*field;
    for (T value : bad) {
      pc.*field = value;
      try {
        BinPickingPipeline p(cam, pc);
        ADD_FAILURE() << name << " " << value << " accepted";
      } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
      }
    }
    pc.*field = good;
  };
  refuses("search_downsample", &PipelineConfig::search_downsample, {0, 5});
  refuses("search_rounds", &PipelineConfig::search_rounds, {0, 5});
  refuses("round_hypotheses", &PipelineConfig::round_hypotheses, {0});
  refuses("escalate_query_guides", &PipelineConfig::escalate_query_guides, {0});
  refuses("escalate_hypotheses", &PipelineConfig::escalate_hypotheses, {0});
  refuses("rescore_hypotheses", &PipelineConfig::rescore_hypotheses, {-1});
  refuses("depth_starts", &PipelineConfig::depth_starts, {-1});
  // The ranking's settings.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  refuses("fit_score_gate_px", &PipelineConfig::fit_score_gate_px, {0.0, -1.0, nan, 1.5});  // 1.5 < inlier cost 2
  refuses("fit_inlier_cost_px", &PipelineConfig::fit_inlier_cost_px, {0.0, nan, 5.0});      // 5 > score gate 4
  refuses("unexplained_weight", &PipelineConfig::unexplained_weight, {-0.1, nan});
  refuses("escalate_max_cost_px", &PipelineConfig::escalate_max_cost_px, {-1.0, nan});
  refuses("escalate_below", &PipelineConfig::escalate_below, {-0.1, nan});
  refuses("depth_start_mm", &PipelineConfig::depth_start_mm, {0.0, -2.0, nan});
}

// The bin floor: with the floor where it is, the part is still found; with a floor placed above
// the part's lowest point (an impossible scene, as a wrongly fitted pose deep in the bin is), no
// candidate the pipeline reports reaches below it. Without the floor check the same scene reports
// the part, which reaches below that floor (so the second case tests the check, not the scene).
TEST(Pipeline, NoCandidateReachesBelowTheBinFloor) {
  const fs::path tdb = kTemplates / "diamond.tdb";
  ASSERT_TRUE(fs::exists(tdb)) << tdb;
  const CameraConfig cam = sim_camera();
  const RenderedPart scene = render_part(tdb, cam, 0.4, {330, 230}, 11);
  const Mesh& mesh = scene.db.mesh;
  const double lowest = deepest_mm(mesh, scene.truth);
  auto run = [&](double floor_mm) {
    PipelineConfig pc;
    pc.template_files = {tdb};
    pc.floor.distance_mm = floor_mm;
    return process_once(cam, pc, scene.render.frames);
  };
  // The floor under the part (the render's floor lies deeper still).
  const PipelineResult on_floor = run(lowest);
  ASSERT_FALSE(on_floor.candidates.empty());
  expect_within_bounds(on_floor.candidates.front(), scene);

  BinFloor high;
  high.distance_mm = lowest - 8;
  const PipelineResult unchecked = run(0);
  ASSERT_FALSE(unchecked.candidates.empty());
  EXPECT_TRUE(high.below(mesh, {unchecked.candidates.front().R_m2c, unchecked.candidates.front().t_m2c_mm}));
  const PipelineResult checked = run(high.distance_mm);
  for (const PoseCandidate& c : checked.candidates)
    EXPECT_FALSE(high.below(mesh, {c.R_m2c, c.t_m2c_mm}))
        << "candidate reaches " << high.reach_below(mesh, {c.R_m2c, c.t_m2c_mm}) << " mm below";
}

// set_floor moves the floor of the next cycles, as if the pipeline had been configured with it; a
// bad floor is refused and leaves the one in use.
TEST(Pipeline, SetFloorActsAsTheConfiguredFloor) {
  const fs::path tdb = kTemplates / "diamond.tdb";
  ASSERT_TRUE(fs::exists(tdb)) << tdb;
  const CameraConfig cam = sim_camera();
  const RenderedPart scene = render_part(tdb, cam, 0.4, {330, 230}, 11);
  const Mesh& mesh = scene.db.mesh;
  PipelineConfig pc;
  pc.template_files = {tdb};
  BinPickingPipeline pipeline(cam, pc);
  PipelineResult result;
  auto run = [&] {
    pipeline.process(scene.render.frames, 0, std::chrono::steady_clock::now() + std::chrono::seconds(30), result);
  };
  BinFloor high;
  high.distance_mm = deepest_mm(mesh, scene.truth) - 8;
  auto best_below = [&] {
    return !result.candidates.empty() &&
           high.below(mesh, {result.candidates.front().R_m2c, result.candidates.front().t_m2c_mm});
  };
  run();
  EXPECT_TRUE(best_below());  // no floor known: the part itself reaches below `high`
  pipeline.set_floor(high);
  BinFloor bad = high;
  bad.normal = {0, 0, -1};  // pointing back at the camera
  EXPECT_THROW(pipeline.set_floor(bad), std::invalid_argument);
  run();
  for (const PoseCandidate& c : result.candidates)
    EXPECT_FALSE(high.below(mesh, {c.R_m2c, c.t_m2c_mm}))
        << "candidate reaches " << high.reach_below(mesh, {c.R_m2c, c.t_m2c_mm}) << " mm below";
  pipeline.set_floor(BinFloor{});
  run();
  EXPECT_TRUE(best_below());
}

// Floor starts are a second start, not a constraint: a part held 15 mm above the floor (on
// something, as in a full bin) is fitted again from the floor, and the fit climbs back to it.
TEST(Pipeline, FloorStartsLeaveAPartThatDoesNotRestOnTheFloorWhereItIs) {
  const fs::path tdb = kTemplates / "tnut.tdb";
  ASSERT_TRUE(fs::exists(tdb)) << tdb;
  const CameraConfig cam = sim_camera();
  const RenderedPart scene = render_part(tdb, cam, -0.6, {300, 260}, 13);
  PipelineConfig pc;
  pc.template_files = {tdb};
  pc.floor.distance_mm = deepest_mm(scene.db.mesh, scene.truth) + 15;
  ASSERT_GT(pc.floor_starts, 0);
  BinPickingPipeline pipeline(cam, pc);
  PipelineResult result;
  pipeline.process(scene.render.frames, 0, std::chrono::steady_clock::now() + std::chrono::seconds(30), result);
  ASSERT_FALSE(result.candidates.empty());
  const PoseCandidate& best = result.candidates.front();
  expect_within_bounds(best, scene);
  EXPECT_LT(pc.floor.reach_below(scene.db.mesh, {best.R_m2c, best.t_m2c_mm}), -10.0);  // still well above the floor
}

// The render-based refinement stage (off by default with one view, see PipelineConfig) still runs
// when asked: the refined best candidate stays within the correctness bounds.
TEST(Pipeline, RefinesTheBestCandidateWhenAsked) {
  const fs::path tdb = kTemplates / "tnut.tdb";
  ASSERT_TRUE(fs::exists(tdb)) << tdb;
  const CameraConfig cam = sim_camera();
  PipelineConfig pc;
  pc.template_files = {tdb};
  pc.refine_candidates = 1;
  BinPickingPipeline pipeline(cam, pc);
  const RenderedPart scene = render_part(tdb, cam, 0.7, {300, 250}, 7);
  PipelineResult result;
  pipeline.process(scene.render.frames, 0, std::chrono::steady_clock::now() + std::chrono::seconds(30), result);
  ASSERT_FALSE(result.candidates.empty());
  EXPECT_GT(result.times.refine_ms, 0.0);
  expect_within_bounds(result.candidates.front(), scene);
}

// A deadline shorter than the search returns soon after it, flagged degraded, with picks, and
// only poses it fitted (never a pose the fit skipped). A generous one is not degraded. A deadline
// already past leaves no time to search: degraded, and still no unfitted pose.
TEST(Pipeline, DeadlineCutsTheSearchAndTheFitShort) {
  std::vector<fs::path> all;
  for (const char* p : {"breaker", "diamond", "ellipse", "tnut", "knob", "wheel"})
    all.push_back(kTemplates / (std::string(p) + ".tdb"));
  const CameraConfig cam = sim_camera();
  PipelineConfig pc;
  pc.template_files = all;
  BinPickingPipeline pipeline(cam, pc);
  const TemplateDatabase db = load_template_database(all[3]);
  MfcRenderer renderer(cam);
  const int part_id = renderer.add_mesh(db.mesh);
  const int floor_id = renderer.add_mesh(make_plane(600));
  const MfcRender render =
      render_on_floor(renderer, part_id, floor_id, db, upper_view_pose(db, cam, 0.3, {330, 230}), 11);
  // The machine is shared, and the load on it changes within a test (ctest runs two at a time,
  // each with its own threads): a cut cycle is compared with a full cycle run just before it,
  // and the best of up to three such pairs counts. Each cut cycle must be cut short and give
  // picks. (CI once failed with one full cycle of 76 ms measured while the machine was quiet
  // and three cut cycles of at least 93 ms after load arrived.)
  PipelineResult full, cut;
  double ratio = std::numeric_limits<double>::infinity(), took_ms = 0, full_ms = 0;
  for (int attempt = 0; attempt < 3 && !(ratio < 0.75); ++attempt) {
    pipeline.process(render.frames, 0, std::chrono::steady_clock::now() + std::chrono::seconds(60), full);
    EXPECT_FALSE(full.degraded);
    const double budget_ms = full.times.total_ms / 4;
    const auto start = std::chrono::steady_clock::now();
    pipeline.process(render.frames, 0, start + std::chrono::microseconds(static_cast<int64_t>(budget_ms * 1000)), cut);
    const double took = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    EXPECT_TRUE(cut.degraded);
    EXPECT_LT(cut.views_searched, full.views_searched);
    EXPECT_FALSE(cut.candidates.empty()) << "a late cycle still gives its best-so-far picks";
    for (const auto& c : cut.candidates) EXPECT_GT(c.t_m2c_mm[2], 100.0) << "an unfitted (identity) pose came out";
    if (took / full.times.total_ms < ratio) {
      ratio = took / full.times.total_ms;
      took_ms = took;
      full_ms = full.times.total_ms;
    }
  }
  // Cut short: well under the full cycle run just before it (a ratio within one run, not a time).
  EXPECT_LT(ratio, 0.75) << "cut " << took_ms << " ms, full " << full_ms << " ms";
  PipelineResult late;
  pipeline.process(render.frames, 0, std::chrono::steady_clock::now() - std::chrono::seconds(1), late);
  EXPECT_TRUE(late.degraded);
  for (const auto& c : late.candidates) EXPECT_GT(c.t_m2c_mm[2], 100.0);
}

// Whatever the deadline, a cycle that is not flagged degraded is the cycle an unlimited deadline
// gives, bit for bit: every step the deadline can skip (search views, fits, the leaders'
// checks, alternatives, the edge-offset fit) flags the cycle when it does. Budgets from a
// twentieth of a full cycle to well past its end, on six part types (escalation off: like a later round it
// only adds candidates, and its skipping is by design not a degradation).
TEST(Pipeline, ACycleNotDegradedIsTheFullCycle) {
  const CameraConfig cam = sim_camera();
  const SixParts six = render_six_parts(cam);
  PipelineConfig pc;
  pc.template_files = six.files;
  pc.escalate_below = 0;
  BinPickingPipeline pipeline(cam, pc);
  PipelineResult full, cut;
  pipeline.process(six.render.frames, 0, std::chrono::steady_clock::now() + std::chrono::seconds(60), full);
  ASSERT_FALSE(full.degraded);
  ASSERT_GE(full.candidates.size(), 4u);
  int degraded = 0, whole = 0;
  std::vector<double> fractions;
  for (int k = 1; k <= 24; ++k) fractions.push_back(0.05 * k);
  fractions.insert(fractions.end(), {3.0, 10.0});  // whole even when load slows the machine down
  for (const double fraction : fractions) {
    const double budget_ms = full.times.total_ms * fraction;
    pipeline.process(
        six.render.frames, 0,
        std::chrono::steady_clock::now() + std::chrono::microseconds(static_cast<int64_t>(budget_ms * 1e3)), cut);
    if (cut.degraded) {
      ++degraded;
      continue;
    }
    ++whole;
    ASSERT_EQ(cut.candidates.size(), full.candidates.size()) << budget_ms << " ms";
    for (size_t i = 0; i < cut.candidates.size(); ++i) {
      EXPECT_EQ(cut.candidates[i].t_m2c_mm, full.candidates[i].t_m2c_mm) << budget_ms << " ms, candidate " << i;
      EXPECT_EQ(cut.candidates[i].R_m2c, full.candidates[i].R_m2c) << budget_ms << " ms, candidate " << i;
      EXPECT_EQ(cut.candidates[i].score, full.candidates[i].score) << budget_ms << " ms, candidate " << i;
    }
  }
  // Both kinds occur: the budgets reach from well inside the cycle to past its end.
  EXPECT_GT(degraded, 0);
  EXPECT_GT(whole, 0);
}

// A cycle fits fit_candidates hypotheses for one part type and fit_candidates_per_type more for
// each further type it searches: six types 6 + 5 x 3, one type 6, all of that type.
TEST(Pipeline, ACycleOfMoreTypesFitsMoreHypotheses) {
  const CameraConfig cam = sim_camera();
  const SixParts six = render_six_parts(cam);
  PipelineConfig pc;
  pc.template_files = six.files;
  pc.escalate_below = 0;
  pc.fit_candidates = 6;
  pc.fit_candidates_per_type = 3;
  pc.trace = true;
  BinPickingPipeline pipeline(cam, pc);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  PipelineResult all, one;
  pipeline.process(six.render.frames, 0, deadline, all);
  EXPECT_FALSE(all.degraded);
  EXPECT_EQ(all.trace.size(), 21u);
  const int knob = load_template_database(six.files[4]).obj_id;
  pipeline.process(six.render.frames, knob, deadline, one);
  EXPECT_EQ(one.trace.size(), 6u);
  for (const HypothesisTrace& h : one.trace) EXPECT_EQ(h.obj_id, knob);
}

// The coarse-to-fine view search (every 4th view, then the views around the best coarse hits)
// and the search bound shared by the threads, against their slow twins: every view searched and
// no shared bound. The part is found the same, in fewer views; the shared bound changes nothing.
TEST(Pipeline, CoarseToFineViewsAndSharedBoundAgainstTheFullSearch) {
  const std::vector<fs::path> files = {kTemplates / "tnut.tdb", kTemplates / "breaker.tdb"};
  const CameraConfig cam = sim_camera();
  const TemplateDatabase db = load_template_database(files[0]);
  MfcRenderer renderer(cam);
  const int part_id = renderer.add_mesh(db.mesh);
  const int floor_id = renderer.add_mesh(make_plane(600));
  const RigidPose truth = upper_view_pose(db, cam, 0.7, {300, 260});
  const MfcRender render = render_on_floor(renderer, part_id, floor_id, db, truth, 5);
  auto run = [&](int view_stride, bool share) {
    PipelineConfig pc;
    pc.template_files = files;
    pc.view_stride = view_stride;
    pc.share_search_bound = share;
    return process_once(cam, pc, render.frames);
  };
  const PipelineResult full = run(1, false), staged = run(4, true), staged_free = run(4, false);
  const cv::Vec3d centre = truth.R * db.center_mm + truth.t_mm;
  for (const PipelineResult* r : {&full, &staged}) {
    ASSERT_FALSE(r->candidates.empty());
    const PoseCandidate& best = r->candidates.front();
    EXPECT_EQ(best.obj_id, db.obj_id);
    EXPECT_LT(cv::norm(best.R_m2c * db.center_mm + best.t_m2c_mm - centre), 5.0);
    EXPECT_LT(rotation_error_deg(best.R_m2c, truth.R, db.symmetry), 10.0);
  }
  EXPECT_LT(staged.views_searched, full.views_searched / 2);
  ASSERT_EQ(staged.candidates.size(), staged_free.candidates.size());
  for (size_t i = 0; i < staged.candidates.size(); ++i) {
    EXPECT_EQ(staged.candidates[i].obj_id, staged_free.candidates[i].obj_id);
    EXPECT_EQ(staged.candidates[i].view, staged_free.candidates[i].view);
    EXPECT_EQ(staged.candidates[i].t_m2c_mm, staged_free.candidates[i].t_m2c_mm);
  }
  EXPECT_EQ(staged.views_searched, staged_free.views_searched);
}

// PipelineConfig::threads runs the whole cycle, and the result does not depend on it: one, two
// and three threads give the same candidates, bit for bit, on a scene of all six part types
// searched together (what a snapshot replay relies on: mfc-detect must find the cycle's
// candidates again whatever the threads' timing). The caller's own OpenMP setting is left as
// it was.
TEST(Pipeline, ThreadCountChangesNothingButTheThreads) {
  const CameraConfig cam = sim_camera();
  const SixParts six = render_six_parts(cam);
  const int callers = omp_get_max_threads();
  omp_set_num_threads(2);
  std::vector<PipelineResult> results;
  for (int threads : {1, 2, 3}) {
    PipelineConfig pc;
    pc.template_files = six.files;
    pc.threads = threads;
    results.push_back(process_once(cam, pc, six.render.frames));
    EXPECT_EQ(omp_get_max_threads(), 2) << "after a cycle on " << threads << " threads";
  }
  omp_set_num_threads(callers);
  ASSERT_GE(results[0].candidates.size(), 4u);
  for (size_t k = 1; k < results.size(); ++k) {
    const PipelineResult& r = results[k];
    EXPECT_EQ(r.query_lines, results[0].query_lines) << k + 1 << " threads";
    EXPECT_EQ(r.views_searched, results[0].views_searched) << k + 1 << " threads";
    EXPECT_EQ(r.hypotheses, results[0].hypotheses) << k + 1 << " threads";
    ASSERT_EQ(r.candidates.size(), results[0].candidates.size()) << k + 1 << " threads";
    for (size_t i = 0; i < r.candidates.size(); ++i) {
      EXPECT_EQ(r.candidates[i].obj_id, results[0].candidates[i].obj_id) << k + 1 << " threads, candidate " << i;
      EXPECT_EQ(r.candidates[i].view, results[0].candidates[i].view) << k + 1 << " threads, candidate " << i;
      EXPECT_EQ(r.candidates[i].t_m2c_mm, results[0].candidates[i].t_m2c_mm) << k + 1 << " threads, candidate " << i;
      EXPECT_EQ(r.candidates[i].R_m2c, results[0].candidates[i].R_m2c) << k + 1 << " threads, candidate " << i;
      EXPECT_EQ(r.candidates[i].score, results[0].candidates[i].score) << k + 1 << " threads, candidate " << i;
    }
  }
}

// The real-time rule: no heap allocation on the frame path once its buffers have grown
// (operator new counted over the cycles after a warm-up). Two scenes take turns, the part at
// two places and turns, so buffers grown for one and reused for the other count too. The level
// went 36 161 per cycle -> 416 (session 6: kept warps, guide selection, search and DT3/IDT3
// scratch) -> 0 (the converse check's hull and fill, the extractor's clears, the sorts).
TEST(Pipeline, FramePathDoesNotAllocateInSteadyState) {
  const fs::path tdb = kTemplates / "tnut.tdb";
  const TemplateDatabase db = load_template_database(tdb);
  const CameraConfig cam = sim_camera();
  PipelineConfig pc;
  pc.template_files = {tdb};
  // A floor a little below the parts: the floor's slides, refits and floor starts run too; and
  // a second search round.
  pc.floor.distance_mm = db.distance_mm + 15;
  pc.search_rounds = 2;
  // And escalation's wide search in every cycle (no rank reaches 2), and a grasp feature.
  pc.escalate_below = 2;
  pc.grasp_features = {{db.obj_id, GraspFeature{{0, 0, 18}, 6, {0, 0, 1}, 60}}};
  BinPickingPipeline pipeline(cam, pc);
  MfcRenderer renderer(cam);
  const int part_id = renderer.add_mesh(db.mesh);
  const int floor_id = renderer.add_mesh(make_plane(600));
  const MfcRender renders[2] = {
      render_on_floor(renderer, part_id, floor_id, db,
                      coarse_pose(db, TemplatePlacement{3, 0.3, 1.0, {320, 240}}, cam.camera), 100),
      render_on_floor(renderer, part_id, floor_id, db,
                      coarse_pose(db, TemplatePlacement{11, 2.1, 1.05, {250, 300}}, cam.camera), 100)};
  PipelineResult result;
  auto cycle = [&](int i) {
    pipeline.process(renders[i % 2].frames, 0, std::chrono::steady_clock::now() + std::chrono::seconds(30), result);
  };
  for (int i = 0; i < 8; ++i) cycle(i);
  const auto before = mfcd::hal::test::allocation_count();
  for (int i = 0; i < 6; ++i) cycle(i);
  const auto allocations = mfcd::hal::test::allocation_count() - before;
  EXPECT_EQ(allocations, 0u) << "heap allocations in 6 steady-state cycles";
  ASSERT_FALSE(result.candidates.empty());
  EXPECT_TRUE(result.escalated);
}

// Escalation (PipelineConfig::escalate_below): a cycle whose best fitted hypothesis ranks below
// the threshold searches again over every view and fits more hypotheses; one whose best ranks
// above it, or that is past its deadline, does not. The lone T-nut is found either way.
TEST(Pipeline, EscalatesOnlyWhenTheBestRanksBelowTheThreshold) {
  const fs::path tdb = kTemplates / "tnut.tdb";
  ASSERT_TRUE(fs::exists(tdb)) << tdb;
  const CameraConfig cam = sim_camera();
  const RenderedPart scene = render_part(tdb, cam, 0.7, {300, 250}, 5);
  auto run = [&](double escalate_below) {
    PipelineConfig pc;
    pc.template_files = {tdb};
    pc.escalate_below = escalate_below;
    pc.trace = true;
    return process_once(cam, pc, scene.render.frames);
  };
  auto escalated_hypotheses = [](const PipelineResult& r) {
    int n = 0;
    for (const HypothesisTrace& h : r.trace) n += h.round == 0;
    return n;
  };
  const PipelineResult off = run(0);
  EXPECT_FALSE(off.escalated);
  ASSERT_FALSE(off.candidates.empty());
  expect_within_bounds(off.candidates[0], scene);
  // The lone part ranks well above the default threshold: no escalation by default.
  ASSERT_GT(off.candidates[0].fit_rank, PipelineConfig{}.escalate_below);
  const PipelineResult shipped = run(PipelineConfig{}.escalate_below);
  EXPECT_FALSE(shipped.escalated);
  EXPECT_EQ(shipped.views_searched, off.views_searched);
  EXPECT_EQ(escalated_hypotheses(shipped), 0);
  // Just above the best's rank: the wide search runs, over every view once more.
  const PipelineResult forced = run(off.candidates[0].fit_rank + 0.01);
  EXPECT_TRUE(forced.escalated);
  EXPECT_FALSE(forced.degraded);
  EXPECT_EQ(forced.views_searched, off.views_searched + static_cast<int>(scene.db.views.size()));
  EXPECT_GT(escalated_hypotheses(forced), 0);
  ASSERT_FALSE(forced.candidates.empty());
  expect_within_bounds(forced.candidates[0], scene);
  // Past the deadline: the first search is cut short (degraded) and there is no escalation.
  PipelineConfig pc;
  pc.template_files = {tdb};
  pc.escalate_below = 2;
  BinPickingPipeline pipeline(cam, pc);
  PipelineResult late;
  pipeline.process(scene.render.frames, 0, std::chrono::steady_clock::now() - std::chrono::seconds(1), late);
  EXPECT_TRUE(late.degraded);
  EXPECT_FALSE(late.escalated);
}

// Search rounds: two T-nuts in one image, seen from different views. With one hypothesis, the
// first round can only find one of them; the second searches again without the edges that the
// first one's candidate explains, and its four hypotheses find the other.
TEST(Pipeline, SecondSearchRoundFindsTheOtherInstance) {
  const fs::path tdb = kTemplates / "tnut.tdb";
  ASSERT_TRUE(fs::exists(tdb)) << tdb;
  const CameraConfig cam = sim_camera();
  const TemplateDatabase db = load_template_database(tdb);
  MfcRenderer renderer(cam);
  const int part_id = renderer.add_mesh(db.mesh);
  const int floor_id = renderer.add_mesh(make_plane(600));
  const RigidPose a = coarse_pose(db, TemplatePlacement{3, 0.3, 1.0, {230, 220}}, cam.camera);
  const RigidPose b = coarse_pose(db, TemplatePlacement{11, 2.0, 1.0, {430, 280}}, cam.camera);
  const double floor_z =
      std::max((a.R * db.center_mm + a.t_mm)[2], (b.R * db.center_mm + b.t_mm)[2]) + db.diameter_mm / 2 + 10;
  const ScenePart parts[3] = {{part_id, a.R, a.t_mm, Material::matte(0.6f)},
                              {part_id, b.R, b.t_mm, Material::matte(0.6f)},
                              {floor_id, cv::Matx33d::eye(), {0, 0, floor_z}, Material::matte(0.5f)}};
  MfcRender render;
  renderer.render(parts, render, 21);
  auto finds = [&](const PipelineResult& r, const RigidPose& truth) {
    const cv::Vec3d centre = truth.R * db.center_mm + truth.t_mm;
    for (const PoseCandidate& c : r.candidates)
      if (cv::norm(c.R_m2c * db.center_mm + c.t_m2c_mm - centre) <= 5.0 &&
          rotation_error_deg(c.R_m2c, truth.R, db.symmetry) <= 10.0)
        return true;
    return false;
  };
  auto run = [&](int rounds) {
    PipelineConfig pc;
    pc.template_files = {tdb};
    pc.fit_candidates = 1;
    pc.round_hypotheses = 4;
    pc.search_rounds = rounds;
    pc.trace = true;
    return process_once(cam, pc, render.frames);
  };
  const PipelineResult one = run(1);
  EXPECT_EQ(one.rounds, 1);
  ASSERT_EQ(one.candidates.size(), 1u);
  EXPECT_NE(finds(one, a), finds(one, b)) << "one round, one hypothesis: exactly one of the two";
  for (int rounds : {2, 3}) {
    const PipelineResult more = run(rounds);
    EXPECT_EQ(more.rounds, rounds);
    EXPECT_FALSE(more.degraded);
    EXPECT_TRUE(finds(more, a)) << rounds << " rounds";
    EXPECT_TRUE(finds(more, b)) << rounds << " rounds";
    int later = 0;
    for (const HypothesisTrace& h : more.trace) later += h.round > 1;
    EXPECT_GE(later, 1) << "the trace names the round of each hypothesis";
  }
  // A cycle already past its deadline runs no later round (and the first is flagged degraded).
  PipelineConfig pc;
  pc.template_files = {tdb};
  pc.search_rounds = 2;
  BinPickingPipeline pipeline(cam, pc);
  PipelineResult late;
  pipeline.process(render.frames, 0, std::chrono::steady_clock::now() - std::chrono::seconds(1), late);
  EXPECT_TRUE(late.degraded);
  EXPECT_EQ(late.rounds, 1);
}

// Plates on their rim: seen edge on, the diamond's and the ellipse's outlines change little when
// they turn about their own axis. Each plate, alone on the floor at a view within about 15 degrees
// of edge on (tilted by up to 4 degrees more and turned in the image), is found within the
// correctness bounds. (Alone, the fit gets there without the plate turns too: with them disabled
// all 6 were within the bounds as well. In a bin, fits from search hypotheses stop 10-25 degrees
// off, which the plate turns correct; that is measured on the mfc-sim sets, docs/pose.md.)
TEST(Pipeline, FindsAPlateStandingOnItsRim) {
  const CameraConfig cam = sim_camera();
  for (const char* part : {"diamond", "ellipse"}) {
    const fs::path tdb = kTemplates / (std::string(part) + ".tdb");
    ASSERT_TRUE(fs::exists(tdb)) << tdb;
    const TemplateDatabase db = load_template_database(tdb);
    PipelineConfig pc;
    pc.template_files = {tdb};
    BinPickingPipeline pipeline(cam, pc);
    MfcRenderer renderer(cam);
    const int part_id = renderer.add_mesh(db.mesh);
    const int floor_id = renderer.add_mesh(make_plane(600));
    std::mt19937 rng(std::hash<std::string>{}(part) % 1000 + 7);
    std::vector<int> rim_views;
    for (int v = 0; v < static_cast<int>(db.views.size()); ++v)
      if (std::abs(db.views[static_cast<size_t>(v)].view_direction[2]) < 0.25) rim_views.push_back(v);
    ASSERT_FALSE(rim_views.empty());
    for (int trial = 0; trial < 3; ++trial) {
      const int view = rim_views[std::uniform_int_distribution<size_t>(0, rim_views.size() - 1)(rng)];
      const RigidPose truth = pose_between_views(db, cam, view, {120, 80}, rng);
      const cv::Vec3d centre = truth.R * db.center_mm + truth.t_mm;
      const MfcRender render = render_on_floor(renderer, part_id, floor_id, db, truth, 200 + trial);
      PipelineResult result;
      pipeline.process(render.frames, 0, std::chrono::steady_clock::now() + std::chrono::seconds(30), result);
      ASSERT_FALSE(result.candidates.empty()) << part << " view " << view;
      const PoseCandidate& best = result.candidates.front();
      const double dt = cv::norm(best.R_m2c * db.center_mm + best.t_m2c_mm - centre);
      const double dr = rotation_error_deg(best.R_m2c, truth.R, db.symmetry);
      std::printf("%s trial %d: view %d (z %.2f) -> %d, centre error %.2f mm, rotation error %.2f deg, rank %.3f\n",
                  part, trial, view, db.views[static_cast<size_t>(view)].view_direction[2], best.view, dt, dr,
                  best.fit_rank);
      EXPECT_LE(dt, 5.0) << part << " trial " << trial;
      EXPECT_LE(dr, 10.0) << part << " trial " << trial;
    }
  }
}

// A diamond standing on its rim on the bin floor, seen from above: a strip whose length is all
// that tells its spin about its normal, so a pose spun 35-54 degrees at a compensating distance
// fits nearly as well and can rank first. The spin check compares the best hypotheses with the
// lower-ranked spin rivals at their place, where the wrong spin's strip ends lie over bare floor.
// The two poses are mfc-sim's (single parts on an empty floor, seed 3001, scene 2, images 13 and
// 25), with the floor at 300 mm as there, each rendered with 4 noise seeds (RimDiamonds). Measured:
// 4 of the 8 within 5 mm and 10 degrees (5 with the edge offset correction, one of them at 9.9
// degrees), 0 of 8 with the check off (kSpinCheckLeaders 0: 11-54 degrees off). The others stay
// 10-54 degrees off: the check helps, it does not settle every case.
TEST(Pipeline, TellsTheSpinOfADiamondOnItsRim) {
  ASSERT_TRUE(fs::exists(kTemplates / "diamond.tdb"));
  RimDiamonds scene;
  const TemplateDatabase& db = scene.db;
  BinPickingPipeline pipeline(scene.cam, scene.config());
  int right = 0;
  for (int k = 0; k < 8; ++k) {
    const RigidPose& truth = scene.truth(k);
    EXPECT_NEAR(deepest_mm(db.mesh, truth), 300.0, 0.5) << "the diamond rests on the floor";
    const MfcRender render = scene.render(k);
    PipelineResult result;
    pipeline.process(render.frames, 0, std::chrono::steady_clock::now() + std::chrono::seconds(30), result);
    ASSERT_FALSE(result.candidates.empty()) << "pose " << k;
    const PoseCandidate& best = result.candidates.front();
    const cv::Vec3d centre = truth.R * db.center_mm + truth.t_mm;
    const double dt = cv::norm(best.R_m2c * db.center_mm + best.t_m2c_mm - centre);
    const double dr = rotation_error_deg(best.R_m2c, truth.R, db.symmetry);
    std::printf("pose %d, noise seed %d: centre error %.2f mm, rotation error %.2f deg, rank %.3f\n", k % 2, 31 + k, dt,
                dr, best.fit_rank);
    right += dt <= 5.0 && dr <= 10.0;
  }
  EXPECT_GE(right, 3) << "of 8 renders";
}

// Depth starts (PipelineConfig::depth_starts) only ever take a fit that ranks higher: with the
// checks that could reorder the leaders off (turned-over checks, escalation), the best candidate
// ranks at least as high with them as without, on every render of the two diamonds on their rim
// searched at a distance 12 mm off their own; and on some render they raise it (they do something).
TEST(Pipeline, DepthStartsOnlyRaiseTheBestRank) {
  ASSERT_TRUE(fs::exists(kTemplates / "diamond.tdb"));
  RimDiamonds scene;
  PipelineConfig pc = scene.config();
  pc.distances_mm = {270};
  pc.flip_checks = 0;
  pc.escalate_below = 0;
  ASSERT_GT(pc.depth_starts, 0);
  BinPickingPipeline with(scene.cam, pc);
  pc.depth_starts = 0;
  BinPickingPipeline without(scene.cam, pc);
  int raised = 0;
  for (int k = 0; k < 8; ++k) {
    const MfcRender render = scene.render(k);
    PipelineResult a, b;
    with.process(render.frames, 0, std::chrono::steady_clock::now() + std::chrono::seconds(30), a);
    without.process(render.frames, 0, std::chrono::steady_clock::now() + std::chrono::seconds(30), b);
    ASSERT_FALSE(a.candidates.empty() || b.candidates.empty()) << "render " << k;
    const double ra = a.candidates.front().fit_rank, rb = b.candidates.front().fit_rank;
    std::printf("render %d: best rank %.4f with depth starts, %.4f without\n", k, ra, rb);
    EXPECT_GE(ra, rb - 1e-12) << "render " << k;
    raised += ra > rb + 1e-6;
  }
  EXPECT_GT(raised, 0);
}

// The edge offset correction (PipelineConfig::edge_offset_correction): the same two diamonds
// standing on their rim as above, 4 noise seeds each, found with and without it. Without it the
// strip, whose long edges lie diagonal in the image but near an image axis in their template views,
// is reported ~2.5 mm too near the camera; with it the depth error is a fraction of that. The
// hypotheses are ranked the same way either way, so both report the same instance.
TEST(Pipeline, ReportsThePlateOnItsRimAtItsDepth) {
  ASSERT_TRUE(fs::exists(kTemplates / "diamond.tdb"));
  RimDiamonds scene;
  const TemplateDatabase& db = scene.db;
  PipelineConfig pc = scene.config();
  BinPickingPipeline corrected(scene.cam, pc);
  pc.edge_offset_correction = false;
  BinPickingPipeline plain(scene.cam, pc);
  double sum_corrected = 0, sum_plain = 0;
  int both = 0;
  for (int k = 0; k < 8; ++k) {
    const RigidPose& truth = scene.truth(k);
    const MfcRender render = scene.render(k);
    const cv::Vec3d centre = truth.R * db.center_mm + truth.t_mm;
    PipelineResult a, b;
    corrected.process(render.frames, 0, std::chrono::steady_clock::now() + std::chrono::seconds(30), a);
    plain.process(render.frames, 0, std::chrono::steady_clock::now() + std::chrono::seconds(30), b);
    ASSERT_FALSE(a.candidates.empty() || b.candidates.empty()) << "pose " << k;
    const PoseCandidate &ca = a.candidates.front(), &cb = b.candidates.front();
    const cv::Vec3d da = ca.R_m2c * db.center_mm + ca.t_m2c_mm - centre,
                    db_ = cb.R_m2c * db.center_mm + cb.t_m2c_mm - centre;
    const double ra = rotation_error_deg(ca.R_m2c, truth.R, db.symmetry),
                 rb = rotation_error_deg(cb.R_m2c, truth.R, db.symmetry);
    std::printf("pose %d, noise seed %d: corrected depth error %+.2f mm (%.1f deg), without %+.2f mm (%.1f deg)\n",
                k % 2, 31 + k, da[2], ra, db_[2], rb);
    // Same instance, same ranking: the correction moves the pose in depth (up to 5 mm at a wrong
    // spin, whose strip ends leave the depth to the strip's width) and turns it by a few degrees.
    EXPECT_LT(cv::norm(da - db_), 8.0) << "pose " << k;
    EXPECT_LT(rotation_error_deg(ca.R_m2c, cb.R_m2c, db.symmetry), 5.0) << "pose " << k;
    if (cv::norm(db_) <= 5.0 && rb <= 10.0) sum_corrected += da[2], sum_plain += db_[2], ++both;
  }
  ASSERT_GE(both, 3) << "renders found within 5 mm and 10 degrees";
  std::printf("mean depth error over %d renders: %+.2f mm corrected, %+.2f mm without\n", both, sum_corrected / both,
              sum_plain / both);
  EXPECT_LT(sum_plain / both, -1.5);
  EXPECT_LT(std::abs(sum_corrected / both), 1.0);
}

// Grasp features (PipelineConfig::grasp_features, vision/pose/grasp_visibility.hpp) on a
// rendered scene: two T-nuts lying with their hole up, a plate hovering 8 mm over the hole of
// the first. Both are found; the covered hole's candidate gets a low grasp visibility and the
// free one a high one, as the render itself says (the share of each hole's disc where the T-nut
// is the visible surface), and the candidates carry what grasp_visibility() gives at their pose.
TEST(Pipeline, GraspVisibilityTellsACoveredHoleFromAFreeOne) {
  const fs::path tdb = kTemplates / "tnut.tdb";
  ASSERT_TRUE(fs::exists(tdb)) << tdb;
  const CameraConfig cam = sim_camera();
  const TemplateDatabase db = load_template_database(tdb);
  int view = 0;
  while (db.views[view].view_direction[2] < 0.97) ++view;  // seen from the hole's side
  const RigidPose a = coarse_pose(db, TemplatePlacement{view, 0.4, 1.0, {230, 220}}, cam.camera);
  const RigidPose b = coarse_pose(db, TemplatePlacement{view, 2.0, 1.0, {430, 270}}, cam.camera);
  GraspFeature top, bottom;
  top.point_mm = {0, 0, 18}, top.radius_mm = 6, top.approach = {0, 0, 1}, top.max_tilt_deg = 45;
  bottom.point_mm = {0, 0, 0}, bottom.radius_mm = 6, bottom.approach = {0, 0, -1}, bottom.max_tilt_deg = 45;
  ASSERT_TRUE(grasp_faces_camera(top, a) && grasp_faces_camera(top, b));
  MfcRenderer renderer(cam);
  const int part_id = renderer.add_mesh(db.mesh);
  const int plate_id = renderer.add_mesh(make_box(20, 20, 3));
  const int floor_id = renderer.add_mesh(make_plane(600));
  const cv::Vec3d hole_a = a.R * top.point_mm + a.t_mm, hole_b = b.R * top.point_mm + b.t_mm;
  const double floor_z =
      std::max((a.R * db.center_mm + a.t_mm)[2], (b.R * db.center_mm + b.t_mm)[2]) + db.diameter_mm / 2 + 10;
  const ScenePart parts[4] = {{part_id, a.R, a.t_mm, Material::matte(0.6f)},
                              {part_id, b.R, b.t_mm, Material::matte(0.6f)},
                              {plate_id, cv::Matx33d::eye(), hole_a - cv::Vec3d(0, 0, 8), Material::matte(0.7f)},
                              {floor_id, cv::Matx33d::eye(), {0, 0, floor_z}, Material::matte(0.5f)}};
  MfcRender render;
  renderer.render(parts, render, 31);
  // The reference: the share of the hole's disc (6 mm) where the T-nut itself is seen.
  auto seen = [&](const cv::Vec3d& hole, int index) {
    const cv::Point2d c = cam.camera.project(hole);
    const double r = 6 * cam.camera.fx() / hole[2];
    int disc = 0, part = 0;
    for (int y = static_cast<int>(c.y - r); y <= static_cast<int>(c.y + r) + 1; ++y)
      for (int x = static_cast<int>(c.x - r); x <= static_cast<int>(c.x + r) + 1; ++x)
        if ((x - c.x) * (x - c.x) + (y - c.y) * (y - c.y) <= r * r) ++disc, part += render.part_index(y, x) == index;
    return static_cast<double>(part) / disc;
  };
  EXPECT_LT(seen(hole_a, 1), 0.05) << "the plate covers the first hole";
  // The second is free: through the 10 mm bore the floor shows, around it the T-nut.
  EXPECT_GT(seen(hole_b, 2), 0.3) << "the second hole is free";

  PipelineConfig pc;
  pc.template_files = {tdb};
  pc.search_rounds = 2;
  pc.grasp_features = {{db.obj_id, top}, {db.obj_id, bottom}};
  BinPickingPipeline pipeline(cam, pc);
  PipelineResult r;
  pipeline.process(render.frames, 0, std::chrono::steady_clock::now() + std::chrono::seconds(60), r);
  auto candidate_at = [&](const RigidPose& truth) -> const PoseCandidate* {
    const cv::Vec3d centre = truth.R * db.center_mm + truth.t_mm;
    for (const PoseCandidate& c : r.candidates)
      if (cv::norm(c.R_m2c * db.center_mm + c.t_m2c_mm - centre) <= 5.0 &&
          rotation_error_deg(c.R_m2c, truth.R, db.symmetry) <= 10.0)
        return &c;
    return nullptr;
  };
  const PoseCandidate* ca = candidate_at(a);
  const PoseCandidate* cb = candidate_at(b);
  ASSERT_NE(ca, nullptr) << "the covered T-nut is found";
  ASSERT_NE(cb, nullptr) << "the free T-nut is found";
  std::printf("grasp visibility: covered hole %.2f, free hole %.2f\n", ca->grasp_visibility, cb->grasp_visibility);
  EXPECT_LT(ca->grasp_visibility, 0.3);
  EXPECT_GT(cb->grasp_visibility, 0.6);
  for (const PoseCandidate* c : {ca, cb}) {
    const double direct = std::max(pipeline.grasp_visibility(c->obj_id, c->R_m2c, c->t_m2c_mm, top).visible,
                                   pipeline.grasp_visibility(c->obj_id, c->R_m2c, c->t_m2c_mm, bottom).visible);
    EXPECT_DOUBLE_EQ(c->grasp_visibility, direct);
  }
  // Turned over (the hole's top side away from the camera), only the bottom feature could count,
  // and it faces away too at these poses: nothing to take it by.
  const RigidPose flipped{a.R * cv::Matx33d(1, 0, 0, 0, -1, 0, 0, 0, -1), a.t_mm};
  EXPECT_FALSE(pipeline.grasp_visibility(db.obj_id, flipped.R, flipped.t_mm, top).faces_camera);
  // A grasp feature for a part type no template file defines is refused.
  pc.grasp_features = {{99, top}};
  EXPECT_THROW(BinPickingPipeline(cam, pc), std::runtime_error);
}

// Each candidate's alternative (PoseCandidate::alternative_*) is a fitted hypothesis at its place
// that ranks no higher than it (the candidate is its place's best), is another answer (moved or
// turned beyond kDistinctPositionMm / kDistinctRotationDeg) and differs from it by at least
// alternative_min_differ of their points (shipped: 0, any). Asking more of the difference can only
// find an alternative at most as high; asking every point to differ, lower still.
TEST(Pipeline, AlternativeIsTheBestDistinctHypothesisAtThePlace) {
  RimDiamonds scene;
  auto run = [&](double min_differ, int k) {
    PipelineConfig pc = scene.config();
    pc.alternative_min_differ = min_differ;
    BinPickingPipeline pipeline(scene.cam, pc);
    PipelineResult r;
    pipeline.process(scene.render(k).frames, 0, std::chrono::steady_clock::now() + std::chrono::seconds(30), r);
    return r.candidates;
  };
  int with_alternative = 0;
  const PipelineConfig shipped_config;
  ASSERT_EQ(shipped_config.alternative_min_differ, 0);
  for (int k = 0; k < 2; ++k) {
    const auto shipped = run(0.0, k), asking = run(0.25, k), strict = run(1.0, k);
    ASSERT_FALSE(shipped.empty());
    ASSERT_EQ(asking.size(), shipped.size());
    ASSERT_EQ(strict.size(), shipped.size());
    for (size_t i = 0; i < shipped.size(); ++i) {
      const PoseCandidate& c = shipped[i];
      EXPECT_EQ(asking[i].fit_rank, c.fit_rank);  // the alternative changes nothing else
      // The score is the confidence model's probability of what was measured; ambiguous is the
      // alternative's support below the threshold.
      EXPECT_NEAR(c.score, shipped_config.confidence.probability(c.evidence()), 1e-12) << "candidate " << i;
      EXPECT_EQ(c.ambiguous, c.has_alternative && c.alternative_support < shipped_config.ambiguous_support)
          << "candidate " << i;
      if (!strict[i].has_alternative) {
        EXPECT_FALSE(strict[i].ambiguous) << "candidate " << i;
      }
      if (c.has_alternative) {
        ++with_alternative;
        EXPECT_LE(c.alternative_rank, c.fit_rank) << "candidate " << i;
        EXPECT_GE(c.alternative_differs, 0.0) << "candidate " << i;
        EXPECT_LE(c.alternative_differs, 1.0);
        EXPECT_GE(c.alternative_support, -1.0);
        EXPECT_LE(c.alternative_support, 1.0);
      }
      if (asking[i].has_alternative) {
        EXPECT_GE(asking[i].alternative_differs, 0.25) << "candidate " << i;
        ASSERT_TRUE(c.has_alternative) << "candidate " << i;
        EXPECT_LE(asking[i].alternative_rank, c.alternative_rank) << "candidate " << i;
      }
      if (strict[i].has_alternative) {
        ASSERT_TRUE(asking[i].has_alternative) << "candidate " << i;
        EXPECT_LE(strict[i].alternative_rank, asking[i].alternative_rank) << "candidate " << i;
      }
    }
  }
  EXPECT_GT(with_alternative, 0);  // a diamond on its rim always has a competing spin
}
