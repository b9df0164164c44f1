// mfc-second-look: how much a second look (SecondLook, paper Sec. 4.5) changes the pick against one
// view (docs/pose.md, "Second look"), with a bench split's parts, camera and templates. Two sources
// of scenes:
//   --views sim: bins simulated by our renderer (BinSimulator): 1-3 part types of the split dropped
//     into a bin, the first frame set searched per type present, the camera moved (to the best
//     candidate's suggested second location, or turned about the bin's centre) and the scene
//     rendered again;
//   --views dataset: the dataset's own scenes with two images whose cameras it gives
//     (scene_camera.json cam_R_w2c / cam_t_w2c: the generalization bench's Blender scenes made
//     with a second view), image 0 the first look and image 1 the second, the motion between them
//     the dataset's.
// Then fused. A trial is right as in the generalization bench: some instance within 5 mm and 10
// degrees after the model's symmetries. JSON (--out) and a table on stdout.
#include "motion/pick_choice.hpp"
#include "tools/common/cli.hpp"
#include "tools/eval/pose_error.hpp"
#include "vision/dataset/bin_scene.hpp"
#include "vision/dataset/bop_dataset.hpp"
#include "vision/pipeline/second_look.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <random>
#include <set>

using namespace mfcd::vision;
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

struct Options {
  std::string dataset, templates, out, motion = "suggest", views = "sim";
  int scenes = 20, parts_per_image = 8, types_min = 1, types_max = 3;
  uint64_t seed = 1;
  double tilt_deg = SecondLookParams{}.tilt_deg;
};

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

struct Part {
  PartModel model;
  std::vector<cv::Matx44d> symmetries;
  cv::Vec3d centre;
};

// Error of the pose against the nearest instance of its type that is right, else the instance
// nearest in position (the one the estimate sits on).
struct Scored {
  bool right = false;
  double position_mm = 1e9, rotation_deg = 1e9;
};
json scored_json(const Scored& s) {
  return {{"right", s.right}, {"position_mm", s.position_mm}, {"rotation_deg", s.rotation_deg}};
}

// The true instances of an image: obj_id, pose, visible share.
struct Instance {
  int obj_id = 0;
  cv::Matx33d R;
  cv::Vec3d t_mm;
  double visib_fract = 0;
};
std::vector<Instance> instances_of(const std::vector<PartInstance>& sim) {
  std::vector<Instance> out;
  for (const auto& g : sim) out.push_back({g.obj_id, g.R, g.t_mm, g.visib_fract});
  return out;
}
Scored score(const cv::Matx33d& R, const cv::Vec3d& t, const Part& part, const std::vector<Instance>& truth,
             int obj_id) {
  const mfcd::eval::Criterion crit;
  Scored best;
  for (const auto& g : truth) {
    if (g.obj_id != obj_id) continue;
    const auto e = mfcd::eval::pose_error(R, t, g.R, g.t_mm, part.symmetries, part.centre);
    const bool right = crit.accepts(e);
    if ((right && !best.right) || (right == best.right && e.position_mm < best.position_mm)) {
      best.right = right;
      best.position_mm = e.position_mm;
      best.rotation_deg = e.rotation_deg;
    }
  }
  return best;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// What the trials add up to.
struct Tally {
  int n = 0, right_first = 0, right_fused = 0, fixed = 0, broken = 0, skipped_scenes = 0;
  int right_when_unsure = 0, looks_when_unsure = 0;  // a second look only where the first is unsure
  std::vector<double> rot_first, rot_fused, first_ms, fuse_ms;
  json trials = json::array();
};

// The first view's frames are searched for obj; second(best) gives the camera motion and the second
// frame set for the first view's best candidate. One trial into the tally.
void run_trial(SecondLook& look, const Part& part, const std::vector<Instance>& truth, int obj, const MfcFrames& first,
               const std::function<std::pair<RigidTransform, MfcFrames>(const PoseCandidate&)>& second, json trial,
               Tally& t) {
  double best_visib = 0;
  for (const auto& g : truth)
    if (g.obj_id == obj) best_visib = std::max(best_visib, g.visib_fract);
  trial["obj_id"] = obj;
  trial["best_visib_fract"] = best_visib;
  const auto far = Clock::now() + std::chrono::hours(1);
  auto t0 = Clock::now();
  PipelineResult one;
  look.first().process(first, obj, far, one);
  t.first_ms.push_back(ms_since(t0));
  ++t.n;
  if (one.candidates.empty()) {
    trial["first"] = nullptr;
    t.trials.push_back(trial);
    return;
  }
  const PoseCandidate& best = one.candidates.front();
  const auto [motion, frames] = second(best);
  t0 = Clock::now();
  SecondLookResult fused;
  look.fuse(one, frames, motion, obj, far, fused);
  t.fuse_ms.push_back(ms_since(t0));
  const Scored a = score(best.R_m2c, best.t_m2c_mm, part, truth, obj);
  Scored b;
  if (!fused.candidates.empty())
    b = score(fused.candidates.front().R_m2c, fused.candidates.front().t_m2c_mm, part, truth, obj);
  t.right_first += a.right;
  t.right_fused += b.right;
  t.fixed += b.right && !a.right;
  t.broken += a.right && !b.right;
  if (a.position_mm <= 5) t.rot_first.push_back(a.rotation_deg);
  if (b.position_mm <= 5) t.rot_fused.push_back(b.rotation_deg);
  // Unsure, as the cell's pick judges it (motion::PickChoiceConfig's defaults): the first view's
  // best is ambiguous or scores below pick.min_score. A cell would look again then.
  const mfcd::motion::PickChoiceConfig pick_config;
  const bool unsure = (pick_config.skip_ambiguous && best.ambiguous) || best.score < pick_config.min_score;
  t.right_when_unsure += unsure ? b.right : a.right;
  t.looks_when_unsure += unsure;
  trial["first_score"] = best.score;
  trial["first_ambiguous"] = best.ambiguous;
  trial["first"] = scored_json(a);
  trial["fused"] = scored_json(b);
  trial["fused_from"] = fused.candidates.empty() ? 0 : fused.candidates.front().proposed_by;
  trial["first_ms"] = t.first_ms.back();
  trial["fuse_ms"] = t.fuse_ms.back();
  // Every fused candidate with what the fused confidence model takes (fit_fused_confidence.py
  // fits it on these).
  json fused_candidates = json::array();
  for (const SecondLookCandidate& c : fused.candidates) {
    const FusedEvidence e = c.evidence();
    fused_candidates.push_back({{"right", score(c.R_m2c, c.t_m2c_mm, part, truth, obj).right},
                                {"score", c.score},
                                {"rank_first", e.rank_first},
                                {"rank_second", e.rank_second},
                                {"has_alternative", e.has_alternative},
                                {"alternative_margin", e.alternative_margin},
                                {"proposed_by", c.proposed_by}});
  }
  trial["fused_candidates"] = fused_candidates;
  trial["fused_score"] = fused.candidates.empty() ? 0.0 : fused.candidates.front().score;
  t.trials.push_back(trial);
}

// --views sim: bins of 1-3 of the split's types simulated by our renderer, seen again from the
// motion asked for.
void simulated_scenes(const Options& o, const CameraConfig& camera, const std::map<int, Part>& parts, SecondLook& look,
                      Tally& t) {
  std::vector<int> ids;
  for (const auto& [id, p] : parts) ids.push_back(id);
  std::mt19937_64 rng(o.seed);
  for (int s = 0; s < o.scenes; ++s) {
    std::vector<int> pick = ids;
    std::shuffle(pick.begin(), pick.end(), rng);
    const int types = std::uniform_int_distribution<int>(o.types_min, std::min<int>(o.types_max, ids.size()))(rng);
    pick.resize(static_cast<size_t>(types));
    std::vector<PartModel> models;
    for (int id : pick) models.push_back(parts.at(id).model);
    BinSceneOptions so;
    so.parts_per_image = o.parts_per_image;
    so.missing.enabled = false;  // the second render has none; both looks see the same kind of images
    std::unique_ptr<BinSimulator> sim;
    try {
      sim = std::make_unique<BinSimulator>(camera, models, so);
    } catch (const std::invalid_argument& e) {  // a part with no stable resting face
      std::fprintf(stderr, "mfc-second-look: scene %d skipped: %s\n", s, e.what());
      ++t.skipped_scenes;
      continue;
    }
    const uint64_t scene_seed = o.seed * 100000 + static_cast<uint64_t>(s);
    const SimulatedImage first = sim->simulate(sim->layout(scene_seed), scene_seed);
    const std::vector<Instance> truth = instances_of(first.instances);
    std::set<int> present;
    for (const auto& g : first.instances) present.insert(g.obj_id);
    for (int obj : present) {
      const auto second = [&](const PoseCandidate& best) {
        RigidTransform motion;
        if (o.motion == "suggest") {
          motion = look.suggest_motion(best);
        } else {
          const cv::Vec3d c(0, 0, camera.working_distance_mm);
          motion.R = rotation_from_angle_axis({o.tilt_deg * CV_PI / 180, 0, 0});
          motion.t = c - motion.R * c;
        }
        std::vector<ScenePart> moved = sim->scene_parts(first.layout);
        for (auto& p : moved) p.R = motion.R * p.R, p.t_mm = motion.R * p.t_mm + motion.t;
        MfcRender render;
        sim->renderer().render(moved, render, scene_seed + 7);
        return std::pair{motion, render.frames};
      };
      run_trial(look, parts.at(obj), truth, obj, first.frames, second, {{"scene", s}, {"types", pick}}, t);
    }
  }
}

// --views dataset: every scene of the dataset whose images 0 and 1 give their cameras' world poses.
void dataset_scenes(const BopDataset& ds, const std::map<int, Part>& parts, SecondLook& look, Tally& t) {
  for (int s : ds.scenes()) {
    const std::vector<int> images = ds.images(s);
    if (images.size() < 2) {
      ++t.skipped_scenes;
      continue;
    }
    const BopSceneCamera c0 = ds.camera(s, images[0]), c1 = ds.camera(s, images[1]);
    if (!c0.has_world_pose || !c1.has_world_pose) {
      ++t.skipped_scenes;
      continue;
    }
    // First camera -> second: p1 = R1 (R0^T (p0 - t0)) + t1.
    const RigidTransform motion =
        RigidTransform{c1.R_w2c, c1.t_w2c_mm} * RigidTransform{c0.R_w2c, c0.t_w2c_mm}.inverse();
    const MfcFrames first = ds.frames(s, images[0]), second = ds.frames(s, images[1]);
    const std::vector<BopGtPose> gt = ds.ground_truth(s, images[0]);
    const std::vector<BopGtInfo> info = ds.ground_truth_info(s, images[0]);
    std::vector<Instance> truth;
    std::set<int> present;
    for (size_t g = 0; g < gt.size(); ++g) {
      truth.push_back({gt[g].obj_id, gt[g].R, gt[g].t_mm, g < info.size() ? info[g].visib_fract : 0.0});
      if (parts.count(gt[g].obj_id)) present.insert(gt[g].obj_id);
    }
    for (int obj : present)
      run_trial(
          look, parts.at(obj), truth, obj, first,
          [&](const PoseCandidate&) {
            return std::pair{motion, second};
          },
          {{"scene", s}}, t);
  }
}

// The table on stdout and, with --out, the JSON.
void print_and_write(const Options& o, const Tally& t, const json& left_out, double setup_s) {
  const json summary = {{"trials", t.n},
                        {"right_first", t.right_first},
                        {"right_fused", t.right_fused},
                        {"fixed", t.fixed},
                        {"broken", t.broken},
                        {"right_second_look_when_unsure", t.right_when_unsure},
                        {"second_looks_when_unsure", t.looks_when_unsure},
                        {"scenes_skipped", t.skipped_scenes},
                        {"parts_left_out", left_out},
                        {"median_rotation_deg_at_right_place_first", median(t.rot_first)},
                        {"median_rotation_deg_at_right_place_fused", median(t.rot_fused)},
                        {"median_first_ms", median(t.first_ms)},
                        {"median_fuse_ms", median(t.fuse_ms)},
                        {"setup_s", setup_s}};
  std::printf("| look | right | of trials | median rotation error at the right place |\n|---|---:|---:|---:|\n");
  std::printf("| first view | %d | %d | %.2f deg |\n", t.right_first, t.n, median(t.rot_first));
  std::printf("| second look (%s, %.0f deg) | %d | %d | %.2f deg |\n",
              o.views == "sim" ? o.motion.c_str() : "the dataset's second view", o.tilt_deg, t.right_fused, t.n,
              median(t.rot_fused));
  std::printf("| second look only where the first is unsure (%d looks) | %d | %d | |\n", t.looks_when_unsure,
              t.right_when_unsure, t.n);
  std::printf("fixed %d, broken %d; first view %.0f ms, second look %.0f ms more (medians); %d scenes skipped\n",
              t.fixed, t.broken, median(t.first_ms), median(t.fuse_ms), t.skipped_scenes);
  if (!o.out.empty()) {
    const json doc = {{"dataset", o.dataset},
                      {"templates", o.templates},
                      {"scenes", o.scenes},
                      {"seed", o.seed},
                      {"parts_per_image", o.parts_per_image},
                      {"tilt_deg", o.tilt_deg},
                      {"motion", o.motion},
                      {"views", o.views},
                      {"summary", summary},
                      {"trials", t.trials}};
    std::ofstream(o.out) << doc.dump(1) << "\n";
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"A second look against one view with a bench split's parts (docs/pose.md, \"Second look\").",
               "mfc-second-look"};
  mfcd::tools::init_app(app);
  Options o;
  app.add_option("--dataset", o.dataset, "a bench split's dataset: models/, camera.yaml")->required();
  app.add_option("--templates", o.templates, "folder of obj_NNNNNN.tdb for the split's camera")->required();
  app.add_option("--out", o.out, "JSON results");
  app.add_option("--views", o.views,
                 "sim: bins simulated by our renderer (default); dataset: the dataset's scenes with two views")
      ->check(CLI::IsMember({"sim", "dataset"}));
  app.add_option("--scenes", o.scenes, "sim: simulated bins (default 20)")->check(CLI::Range(1, 10000));
  app.add_option("--seed", o.seed, "sim: scenes and part types drawn from it (default 1)");
  app.add_option("--parts-per-image", o.parts_per_image, "sim: parts dropped per bin (default 8)")
      ->check(CLI::Range(1, 40));
  app.add_option("--tilt", o.tilt_deg, "sim: second camera's turn about the part, degrees (default 25)")
      ->check(CLI::Range(5.0, 60.0));
  app.add_option("--motion", o.motion,
                 "sim: suggest: to the best candidate (SecondLook::suggest_motion); bin: about the bin's centre")
      ->check(CLI::IsMember({"suggest", "bin"}));
  if (const auto code = mfcd::tools::parse(app, argc, argv)) return *code;
  try {
    const fs::path root = o.dataset;
    const CameraConfig camera = load_camera_config(root / "camera.yaml");
    BopDataset ds(root);
    std::map<int, Part> parts;
    std::vector<fs::path> tdbs;
    for (const auto& [id, info] : ds.models_info()) {
      const fs::path tdb = fs::path(o.templates) / cv::format("obj_%06d.tdb", id);
      if (!fs::exists(tdb)) continue;
      tdbs.push_back(tdb);
      Part p;
      p.model.obj_id = id;
      p.model.name = "obj_" + std::to_string(id);
      p.model.mesh = load_mesh(ds.model_path(id));
      p.symmetries = mfcd::eval::symmetry_transforms(info);
      p.centre = info.min + info.size * 0.5;
      parts.emplace(id, std::move(p));
    }
    if (parts.empty()) throw std::runtime_error("no template of the dataset's models in " + o.templates);
    // A part the simulator cannot drop (no stable resting face) is left out of simulated bins.
    json left_out = json::array();
    for (auto it = parts.begin(); o.views == "sim" && it != parts.end();) {
      try {
        BinSimulator probe(camera, {it->second.model}, BinSceneOptions{});
        ++it;
      } catch (const std::invalid_argument& e) {
        std::fprintf(stderr, "mfc-second-look: obj %d left out: %s\n", it->first, e.what());
        left_out.push_back(it->first);
        it = parts.erase(it);
      }
    }
    PipelineConfig pc;
    pc.template_files = tdbs;
    SecondLookParams sp;
    sp.tilt_deg = o.tilt_deg;
    const auto t_setup = Clock::now();
    SecondLook look(camera, pc, sp);
    const double setup_s = ms_since(t_setup) / 1000;
    Tally t;
    if (o.views == "sim")
      simulated_scenes(o, camera, parts, look, t);
    else
      dataset_scenes(ds, parts, look, t);
    print_and_write(o, t, left_out, setup_s);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mfc-second-look: %s\n", e.what());
    return 1;
  }
  return 0;
}
