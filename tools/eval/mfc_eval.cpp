// mfc-eval: the paper's evaluation (Sec. 5.1.1) on a BOP-layout dataset of simulated bins.
//
//   mfc-eval detect  Table 1 (failure rate and time per part type, CM / OCM / FDCM / LINE-2D),
//                    Fig. 13 (detection rate vs occlusion) and the per-stage timing, as JSON.
//   mfc-eval refine  Table 2 (1-view vs 2-view refinement): needs the multi-view refiner.
//
// tools/eval/report.py turns the JSON into docs/results.md and docs/img/results-*.png;
// `tools/mfc bench paper` runs mfc-sim, mfc-eval and the report in one go.
#include "motion/pick_choice.hpp"
#include "tools/common/build_version.hpp"
#include "tools/eval/detectors.hpp"
#include "tools/eval/eval_options.hpp"
#include "tools/eval/pose_error.hpp"
#include "tools/eval/refine_eval.hpp"
#include "vision/dataset/bop_dataset.hpp"
#include "vision/templates/template_database.hpp"

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

namespace fs = std::filesystem;
using namespace mfcd;
using namespace mfcd::eval;
using nlohmann::json;

namespace {

json times_json(const vision::StageTimes& t) {
  return {{"edges", t.edges_ms}, {"lines", t.lines_ms},   {"dt", t.distance_ms}, {"search", t.search_ms},
          {"pose", t.pose_ms},   {"refine", t.refine_ms}, {"total", t.total_ms}};
}

std::string camera_key(const vision::CameraConfig& c) {
  char key[256];
  std::snprintf(key, sizeof key, "%dx%d fx %.4f fy %.4f cx %.4f cy %.4f, %zu flashes", c.camera.image_size.width,
                c.camera.image_size.height, c.camera.fx(), c.camera.fy(), c.camera.cx(), c.camera.cy(),
                c.flashes.positions_mm.size());
  return key;
}

struct ImageRef {
  int scene = 0, image = 0;
};

int run_detect(const DetectEvalOptions& o) {
  if (!fs::is_directory(o.dataset)) throw std::runtime_error(o.dataset.string() + ": no such dataset folder");
  if (!fs::is_directory(o.templates)) throw std::runtime_error(o.templates.string() + ": no such templates folder");
  const std::vector<PartEntry> parts = read_parts_csv(o.parts);
  vision::BopCameraDefaults defaults;
  if (!o.camera.empty()) defaults = {vision::load_camera_config(o.camera).flashes.positions_mm, o.camera.string()};
  const vision::BopDataset dataset(o.dataset, o.split, defaults);

  // Every object of the dataset must be a known part with a template file.
  std::map<int, fs::path> tdb_of;
  std::map<int, cv::Vec3d> centre_of;                     // bounding-box centre, model frame: the "position" of a part
  std::map<int, std::vector<cv::Matx44d>> symmetries_of;  // --model-symmetries: models_info.json's
  for (const auto& [obj_id, info] : dataset.models_info()) {
    const PartEntry& p = part_by_id(parts, obj_id, (o.dataset / "models/models_info.json").string());
    const fs::path tdb = o.templates / (p.name + ".tdb");
    if (!fs::is_regular_file(tdb))
      throw std::runtime_error(tdb.string() + ": no template file for part '" + p.name + "' (obj_id " +
                               std::to_string(obj_id) + "); run mfc-teach or build the mfc_templates target");
    tdb_of[obj_id] = tdb;
    centre_of[obj_id] = info.min + info.size * 0.5;
    if (o.model_symmetries) symmetries_of[obj_id] = symmetry_transforms(info);
  }
  std::vector<fs::path> tdbs;
  for (const auto& [id, f] : tdb_of) tdbs.push_back(f);

  std::vector<ImageRef> images;
  for (int s : dataset.scenes())
    for (int i : dataset.images(s)) images.push_back({s, i});
  if (images.empty()) throw std::runtime_error(o.dataset.string() + ": no images in split '" + o.split + "'");
  if (o.max_images > 0 && static_cast<int>(images.size()) > o.max_images)
    images.resize(static_cast<size_t>(o.max_images));
  const vision::CameraConfig camera = dataset.camera(images[0].scene, images[0].image).config();
  const std::string key = camera_key(camera);

  // The parts' grasp features (--grasp-features), those of the dataset's parts, and the reference
  // they are checked against: how free a feature of a true instance is in the rendered scene, the
  // best of the part's features.
  std::vector<std::pair<int, vision::GraspFeature>> grasp;
  if (!o.grasp_features.empty())
    for (const auto& f : read_grasp_features_csv(o.grasp_features, parts))
      if (tdb_of.count(f.first)) grasp.push_back(f);
  // Each instance's masks are read once: the trials of every method, their best estimates and
  // the cell's candidates ask again for the same instances.
  std::map<std::tuple<int, int, size_t>, double> true_grasp_of;
  auto true_grasp = [&](const ImageRef& ref, size_t instance, const vision::BopGtPose& gt) {
    const auto which = std::make_tuple(ref.scene, ref.image, instance);
    if (const auto it = true_grasp_of.find(which); it != true_grasp_of.end()) return it->second;
    const cv::Mat1b mask = dataset.mask(ref.scene, ref.image, static_cast<int>(instance));
    const cv::Mat1b visib = dataset.mask_visib(ref.scene, ref.image, static_cast<int>(instance));
    double best = 0;
    for (const auto& [id, feature] : grasp)
      if (id == gt.obj_id)
        best = std::max(best, true_grasp_visibility(feature, gt.R, gt.t_mm, camera.camera, mask, visib));
    return true_grasp_of[which] = best;
  };

  // Each method's detector, built lazily (LINE-2D trains for a while).
  json out;
  out["version"] = version();
  out["commit"] = git_commit();
  out["dataset"] = fs::absolute(o.dataset).string();
  out["split"] = o.split;
  out["images"] = images.size();
  out["criterion"] = {{"max_position_mm", o.criterion.max_position_mm},
                      {"max_rotation_deg", o.criterion.max_rotation_deg},
                      {"rotation", "total angle of R_est R_gt^T, symmetry-aware"},
                      {"position", "distance of the model bounding-box centre"}};
  json jparts = json::array();
  for (const auto& [id, f] : tdb_of) {
    const PartEntry& p = part_by_id(parts, id, o.parts.string());
    // What the templates are, as taught (K and the views kept after folding): the results are
    // only comparable with the same databases.
    const vision::TemplateDatabase db = vision::load_template_database(f);
    if (db.sphere_samples != p.views)
      std::fprintf(stderr, "mfc-eval: %s was taught with K = %d views, the parts table says %d\n", f.string().c_str(),
                   db.sphere_samples, p.views);
    jparts.push_back({{"name", p.name},
                      {"obj_id", id},
                      {"symmetry", o.model_symmetries ? "models_info.json (" +
                                                            std::to_string(symmetries_of.at(id).size()) + " transforms)"
                                                      : p.symmetry.str()},
                      {"templates", f.string()},
                      {"sphere_samples", db.sphere_samples},
                      {"views", db.views.size()}});
  }
  out["parts"] = jparts;
  out["distances_mm"] = o.distances_mm;
  out["floor_mm"] = o.floor_mm;
  out["floor_per_scene"] = o.floor_per_scene;
  out["pick_min_score"] = o.pick_min_score;
  out["pick_skip_ambiguous"] = !o.pick_ambiguous;
  out["refine_candidates"] =
      o.refine_candidates >= 0 ? o.refine_candidates : vision::PipelineConfig{}.refine_candidates;
  out["line2d_options"] = {{"inplane_step_deg", o.line2d.inplane_step_deg},
                           {"view_stride", o.line2d.view_stride},
                           {"min_similarity", o.line2d.min_similarity}};

  // Ground truth once.
  struct ImageGt {
    std::vector<vision::BopGtPose> gt;
    std::vector<vision::BopGtInfo> info;
  };
  std::vector<ImageGt> gts;
  for (const auto& ref : images) {
    const auto cam = dataset.camera(ref.scene, ref.image).config();
    if (camera_key(cam) != key)
      throw std::runtime_error("scene " + std::to_string(ref.scene) + " image " + std::to_string(ref.image) +
                               ": camera " + camera_key(cam) + " differs from the first image's (" + key + ")");
    ImageGt g{dataset.ground_truth(ref.scene, ref.image), dataset.ground_truth_info(ref.scene, ref.image)};
    for (const auto& p : g.gt) part_by_id(parts, p.obj_id, "scene " + std::to_string(ref.scene) + " scene_gt.json");
    gts.push_back(std::move(g));
  }

  auto score = [&](const Estimate& e, const vision::BopGtPose& g) {
    if (o.model_symmetries)
      return pose_error(e.R, e.t_mm, g.R, g.t_mm, symmetries_of.at(g.obj_id), centre_of.at(g.obj_id));
    return pose_error(e.R, e.t_mm, g.R, g.t_mm, part_by_id(parts, g.obj_id, "").symmetry, centre_of.at(g.obj_id));
  };

  const int max_candidates = 8;
  json methods = json::object();
  // --timing-repeats: the detection of `first` run again on the same image and type; the stage
  // times of the fastest run, all runs included. The repeats must give the first run's result
  // (the pipeline is deterministic without a deadline): a repeat that differs is an error.
  auto repeat_timing = [&](Detector& det, const vision::MfcFrames& frames, int obj_id, const Detection& first) {
    vision::StageTimes best = first.times;
    Detection again;
    for (int r = 1; r < o.timing_repeats; ++r) {
      det.detect(frames, obj_id, again);
      const bool same = again.estimates.size() == first.estimates.size() &&
                        (first.estimates.empty() || (again.estimates[0].R == first.estimates[0].R &&
                                                     again.estimates[0].t_mm == first.estimates[0].t_mm));
      if (!same) throw std::runtime_error("--timing-repeats: a repeated detection gave another result");
      if (again.times.total_ms < best.total_ms) best = again.times;
    }
    return times_json(best);
  };
  // The cell's pick among an all-types cycle's candidates (motion::choose_pick, config/sim.yaml's
  // weights: score 1, height 0.5 over 100 mm; --pick-min-score), once without the grasp features
  // (weight 0, as when none are configured) and once with them (--pick-grasp W,V). For each:
  // the chosen candidate, whether its pose is right (Table 1's criterion, any instance of its
  // type) and, if so, how free the grasp feature of that instance truly is.
  // A candidate as the JSON lists it: its part, score and what the pipeline measured of it.
  auto candidate_json = [](const Estimate& e) {
    json entry = {{"obj_id", e.obj_id}, {"score", e.score}};
    for (const auto& [name, value] : e.measures) entry["measures"][name] = value;
    return entry;
  };
  // The bin floor of a scene (--floor scene): the bench renderer's scene_render.json says where its
  // bin stands, as a cell's calibration would.
  std::map<int, double> scene_floors;
  auto floor_of = [&](int scene) {
    if (!o.floor_per_scene) return o.floor_mm;
    if (const auto it = scene_floors.find(scene); it != scene_floors.end()) return it->second;
    char folder[16];
    std::snprintf(folder, sizeof folder, "%06d", scene);
    const fs::path file = o.dataset / o.split / folder / "scene_render.json";
    std::ifstream in(file);
    if (!in) throw std::runtime_error(file.string() + ": cannot open (--floor scene needs each scene's floor)");
    json j;
    try {
      j = json::parse(in);
    } catch (const json::exception& e) {
      throw std::runtime_error(file.string() + ": " + e.what());
    }
    if (!j.contains("floor_distance_mm") || !j["floor_distance_mm"].is_number() ||
        !(j["floor_distance_mm"].get<double>() > 0))
      throw std::runtime_error(file.string() + ": no positive floor_distance_mm");
    return scene_floors[scene] = j["floor_distance_mm"].get<double>();
  };
  auto cell_picks = [&](const ImageRef& ref, const ImageGt& gt, const Detection& det_out) {
    const double floor_mm = floor_of(ref.scene) > 0 ? floor_of(ref.scene) : camera.working_distance_mm;
    std::vector<motion::PickCandidate> candidates;
    for (const Estimate& e : det_out.estimates)
      candidates.push_back({static_cast<float>(e.score), static_cast<float>(floor_mm - e.t_mm[2]),
                            static_cast<float>(e.grasp_visibility), e.ambiguous});
    json settings = json::array();
    // Every candidate the cell chose from: its score, height, grasp estimate, and whether its
    // pose is right (then how free its instance's grasp feature truly is).
    json listed = json::array();
    for (size_t i = 0; i < candidates.size(); ++i) {
      const Estimate& e = det_out.estimates[i];
      bool right = false;
      double free = 0;
      for (size_t j = 0; j < gt.gt.size(); ++j)
        if (gt.gt[j].obj_id == e.obj_id && o.criterion.accepts(score(e, gt.gt[j]))) {
          right = true;
          free = std::max(free, true_grasp(ref, j, gt.gt[j]));
        }
      json entry = candidate_json(e);
      entry.update({{"height_mm", candidates[i].height_mm},
                    {"grasp_estimated", e.grasp_visibility},
                    {"correct", right},
                    {"grasp_true", free}});
      listed.push_back(entry);
    }
    for (const bool with_grasp : {false, true}) {
      motion::PickChoiceConfig pc;
      pc.weight_score = 1.0f, pc.weight_height = 0.5f, pc.height_scale_mm = 100.0f;
      pc.min_score = static_cast<float>(o.pick_min_score);
      pc.skip_ambiguous = !o.pick_ambiguous;
      pc.weight_grasp = with_grasp ? static_cast<float>(o.grasp_weight) : 0.0f;
      pc.min_grasp_visibility = with_grasp ? static_cast<float>(o.min_grasp_visibility) : 0.0f;
      const auto chosen = motion::choose_pick(candidates, pc);
      json c = {{"grasp_weight", pc.weight_grasp},
                {"min_grasp_visibility", pc.min_grasp_visibility},
                {"picked", chosen.has_value()}};
      if (chosen) {
        const json& e = listed[*chosen];
        c["index"] = *chosen, c["obj_id"] = e["obj_id"], c["correct"] = e["correct"], c["grasp_true"] = e["grasp_true"];
        c["grasp_estimated"] = e["grasp_estimated"], c["score"] = e["score"];
      }
      settings.push_back(c);
    }
    return std::make_pair(settings, listed);
  };
  for (const std::string& m : o.methods) {
    std::unique_ptr<Detector> det;
    if (m == "line2d")
      det = make_line2d_detector(camera, tdbs, o.line2d, max_candidates);
    else {
      const auto cost = m == "fdcm" || m == "fdcm-rounds" || m == "fdcm-search" ? vision::PipelineConfig::Cost::fdcm
                        : m == "ocm"                                            ? vision::PipelineConfig::Cost::ocm
                                                                                : vision::PipelineConfig::Cost::cm;
      // fdcm-rounds: the pipeline's second search round on (after --set, which cannot undo it).
      std::vector<std::string> settings = o.pipeline_settings;
      if (m == "fdcm-rounds") settings.push_back("search_rounds=2");
      det = make_pipeline_detector(m, cost, camera, tdbs, o.threads, max_candidates, o.distances_mm,
                                   o.refine_candidates, /*fit_hypotheses=*/m != "fdcm-search", settings, grasp);
    }
    std::fprintf(stderr, "mfc-eval: %s ready (%.1f s setup)\n", m.c_str(), det->setup_seconds());
    json trials = json::array(), instances = json::array();
    Detection d;
    int failures = 0, n_trials = 0;
    double time_sum = 0;
    for (size_t k = 0; k < images.size(); ++k) {
      const ImageRef& ref = images[k];
      const ImageGt& g = gts[k];
      const vision::MfcFrames frames = dataset.frames(ref.scene, ref.image);
      std::set<int> present;
      for (const auto& p : g.gt) present.insert(p.obj_id);
      if (o.floor_per_scene) det->set_floor_mm(floor_of(ref.scene));
      for (int obj_id : present) {
        det->detect(frames, obj_id, d);
        // The best estimate against every instance of the type: correct if it matches any;
        // errors reported for the instance it matches best (smallest position error among the
        // matching ones, else overall).
        json trial = {{"scene", ref.scene},
                      {"image", ref.image},
                      {"obj_id", obj_id},
                      {"times", times_json(d.times)},
                      {"found", !d.estimates.empty()},
                      {"views_searched", d.views_searched},
                      {"evaluated", d.evaluated},
                      {"escalated", d.escalated}};
        bool correct = false, correct_xy = false, correct_per_angle = false;
        double best_visib = 0;
        int n_inst = 0;
        std::vector<size_t> inst;
        // How the best-visible instance lies: the angle between its model z axis and the optical
        // axis (0 = lying flat, facing the camera or away; 90 = standing on edge, for the flat parts).
        double best_tilt_deg = 0;
        for (size_t j = 0; j < g.gt.size(); ++j)
          if (g.gt[j].obj_id == obj_id) {
            inst.push_back(j);
            ++n_inst;
            if (n_inst == 1 || g.info[j].visib_fract > best_visib) {
              best_visib = g.info[j].visib_fract;
              best_tilt_deg = std::acos(std::min(1.0, std::abs(g.gt[j].R(2, 2)))) * 180.0 / CV_PI;
            }
          }
        // The instance of the type an estimate matches best: a correct match first, then the
        // smallest position error (plus the rotation error, `with_rotation`).
        struct InstanceMatch {
          size_t instance = 0;
          PoseError error{1e9, 1e9};
          bool correct = false;
          double order = 1e18;  // the key it was chosen by: smaller is a better match
        };
        auto match = [&](const Estimate& e, bool with_rotation) {
          InstanceMatch best;
          for (size_t j : inst) {
            const PoseError err = score(e, g.gt[j]);
            const bool ok = o.criterion.accepts(err);
            const double order = (ok ? 0 : 1e9) + err.position_mm + (with_rotation ? err.rotation_deg : 0.0);
            if (order < best.order) best = {j, err, ok, order};
          }
          return best;
        };
        if (!d.estimates.empty()) {
          // The same criterion on the position across the optical axis only: how much of the
          // failure is the distance (scale) of a coarse pose.
          for (size_t j : inst) {
            const PoseError e = score(d.estimates[0], g.gt[j]);
            correct_xy = correct_xy || (std::hypot(e.abs_t_mm[0], e.abs_t_mm[1]) <= o.criterion.max_position_mm &&
                                        e.rotation_deg <= o.criterion.max_rotation_deg);
            // The paper's own test (Sec. 5.1.1): each of the three angles within the bound, here
            // the x-y-z Euler angles of the rotation error.
            correct_per_angle =
                correct_per_angle ||
                (e.position_mm <= o.criterion.max_position_mm && e.abs_r_deg[0] <= o.criterion.max_rotation_deg &&
                 e.abs_r_deg[1] <= o.criterion.max_rotation_deg && e.abs_r_deg[2] <= o.criterion.max_rotation_deg);
          }
          const InstanceMatch matched = match(d.estimates[0], false);
          correct = matched.correct;
          trial["position_mm"] = matched.error.position_mm;
          trial["rotation_deg"] = matched.error.rotation_deg;
          trial["d_t_mm"] = {matched.error.d_t_mm[0], matched.error.d_t_mm[1], matched.error.d_t_mm[2]};
          trial["axis_cam"] = {matched.error.axis_cam[0], matched.error.axis_cam[1], matched.error.axis_cam[2]};
          trial["matched_instance"] = matched.instance;
          trial["score"] = d.estimates[0].score;
          trial["matched_visib_fract"] = g.info[matched.instance].visib_fract;
          // The estimate itself (model -> camera, R row-major, t in mm), to score it again by
          // another criterion without running the detector.
          const Estimate& best = d.estimates[0];
          trial["R"] = json::array();
          for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) trial["R"].push_back(best.R(r, c));
          trial["t_mm"] = {best.t_mm[0], best.t_mm[1], best.t_mm[2]};
          // What the pipeline measured of it (its confidence's inputs: PoseCandidate's fields).
          if (!best.measures.empty()) {
            json& measures = trial["measures"];
            for (const auto& [name, value] : best.measures) measures[name] = value;
          }
        }
        // Search miss or cost miss: how the truth scores on this image, by the detector's own
        // ranking measure, against the estimate it chose.
        {
          json truth = json::array();
          for (size_t j : inst)
            if (const auto ps = det->score_pose(obj_id, g.gt[j].R, g.gt[j].t_mm))
              truth.push_back({{"instance", j},
                               {"visib_fract", g.info[j].visib_fract},
                               {"view", ps->view},
                               {"view_angle_deg", ps->view_angle_deg},
                               {"cost_px", ps->cost_px},
                               {"coverage", ps->coverage},
                               {"rank_px", ps->rank_px},
                               {"fit_score", ps->fit_score},
                               {"exact_score", ps->exact_score}});
          // Grasp features (--grasp-features): at each instance's true pose, the estimator's answer
          // and the rendered scene's (true_grasp_visibility), to check the estimator itself.
          if (!grasp.empty())
            for (json& tj : truth) {
              const size_t j = tj["instance"].get<size_t>();
              double estimated = -1;
              bool faces = false;
              for (const auto& [id, feature] : grasp)
                if (id == obj_id)
                  if (const auto gv = det->grasp_visibility(obj_id, g.gt[j].R, g.gt[j].t_mm, feature)) {
                    estimated = std::max(estimated, gv->visible);
                    faces = faces || gv->faces_camera;
                  }
              if (estimated >= 0)
                tj["grasp"] = {
                    {"estimated", estimated}, {"true", true_grasp(ref, j, g.gt[j])}, {"faces_camera", faces}};
            }
          if (o.shading)
            for (json& tj : truth) {
              const auto& pose = g.gt[tj["instance"].get<size_t>()];
              if (const auto sh = det->shading(frames, obj_id, pose.R, pose.t_mm))
                tj.update({{"shading_error", sh->error}, {"shading_pixels", sh->pixels}});
            }
          if (!truth.empty()) trial["truth_scores"] = truth;
          if (!d.estimates.empty())
            trial["best_rank_px"] = d.estimates[0].rank_px, trial["best_score"] = d.estimates[0].rank;
          // The best estimate's grasp visibility (the pipeline's, at its final pose) and, when the
          // estimate is correct, the true one of the instance it matches.
          if (!d.estimates.empty() && !grasp.empty()) {
            trial["grasp_estimated"] = d.estimates[0].grasp_visibility;
            if (correct)
              trial["grasp_true"] = true_grasp(ref, trial["matched_instance"].get<size_t>(),
                                               g.gt[trial["matched_instance"].get<size_t>()]);
          }
        }
        // Where the first correct estimate stands in the detector's ranking (-1: none of them):
        // a ranking miss rather than a search miss when > 0.
        {
          int first = -1;
          for (size_t c = 0; c < d.estimates.size() && first < 0; ++c)
            if (match(d.estimates[c], false).correct) first = static_cast<int>(c);
          trial["first_correct_rank"] = first;
        }
        // Every candidate with its measures and whether its pose is right: the confidence
        // model's data (tools/bench/fit_confidence.py).
        {
          json listed = json::array();
          for (const Estimate& e : d.estimates) {
            const InstanceMatch near = match(e, false);
            json entry = candidate_json(e);
            entry.update({{"correct", near.correct},
                          {"position_mm", near.error.position_mm},
                          {"rotation_deg", near.error.rotation_deg}});
            if (o.shading)
              if (const auto sh = det->shading(frames, e.obj_id, e.R, e.t_mm))
                entry.update({{"shading_error", sh->error}, {"shading_pixels", sh->pixels}});
            listed.push_back(entry);
          }
          trial["candidates"] = listed;
        }
        // With --set trace=1: the hypothesis nearest the truth (any instance), before and after
        // the fit: a search miss has none near it, a fit miss loses it in the fit.
        auto nearest = [&](const std::vector<Estimate>& hyps) {
          json best;
          double best_key = 1e18;
          for (size_t c = 0; c < hyps.size(); ++c) {
            if (hyps[c].obj_id != obj_id) continue;
            const InstanceMatch matched = match(hyps[c], true);
            if (matched.order < best_key)
              best_key = matched.order, best = {{"index", c},
                                                {"instance", matched.instance},
                                                {"correct", matched.correct},
                                                {"position_mm", matched.error.position_mm},
                                                {"rotation_deg", matched.error.rotation_deg},
                                                {"rank", hyps[c].rank}};
          }
          return best;
        };
        if (!d.coarse_hypotheses.empty()) {
          trial["hypotheses"] = d.coarse_hypotheses.size();
          trial["nearest_coarse"] = nearest(d.coarse_hypotheses);
          trial["nearest_fitted"] = nearest(d.fitted_hypotheses);
          // Every fitted hypothesis with its measures and its error against the nearest
          // instance: the data to weigh the rank's terms by.
          json fitted = json::array();
          for (const Estimate& e : d.fitted_hypotheses) {
            json h;
            for (const auto& [name, value] : e.measures) h[name] = value;
            h["rank"] = e.rank;
            // The pose too: how far apart two hypotheses are (a twin at the same place).
            h["R"] = std::vector<double>(e.R.val, e.R.val + 9);
            h["t_mm"] = {e.t_mm[0], e.t_mm[1], e.t_mm[2]};
            const InstanceMatch matched = e.obj_id == obj_id ? match(e, true) : InstanceMatch{};
            h["correct"] = matched.correct;
            if (e.obj_id == obj_id) h["instance"] = matched.instance;
            h["position_mm"] = matched.error.position_mm;
            h["rotation_deg"] = matched.error.rotation_deg;
            fitted.push_back(h);
          }
          trial["fitted"] = fitted;
        }
        if (!o.overlay.empty() && !correct) {
          std::vector<Detector::DrawnPose> drawn;
          for (size_t j : inst) drawn.push_back({g.gt[j].R, g.gt[j].t_mm, cv::Scalar(0, 220, 0)});
          if (trial.contains("nearest_fitted") && !trial["nearest_fitted"].empty()) {
            const Estimate& e = d.fitted_hypotheses[trial["nearest_fitted"]["index"].get<size_t>()];
            drawn.push_back({e.R, e.t_mm, cv::Scalar(0, 230, 255)});
          }
          if (!d.estimates.empty()) drawn.push_back({d.estimates[0].R, d.estimates[0].t_mm, cv::Scalar(0, 0, 255)});
          if (const auto img = det->overlay(obj_id, drawn)) {
            fs::create_directories(o.overlay);
            const fs::path file = o.overlay / (m + "_s" + std::to_string(ref.scene) + "_i" + std::to_string(ref.image) +
                                               "_obj" + std::to_string(obj_id) + ".png");
            if (!cv::imwrite(file.string(), *img)) throw std::runtime_error("cannot write " + file.string());
            trial["overlay"] = file.string();
          }
        }
        trial["correct"] = correct;
        trial["correct_xy"] = correct_xy;
        trial["correct_per_angle"] = correct_per_angle;
        trial["instances"] = n_inst;
        trial["best_visib_fract"] = best_visib;
        trial["best_tilt_deg"] = best_tilt_deg;
        if (m == "fdcm" && o.timing_repeats > 1) trial["times_best"] = repeat_timing(*det, frames, obj_id, d);
        trials.push_back(trial);
        // Per instance (Fig. 13): found by the best estimate, or by any of the top-k estimates
        // where k = the number of instances of its type in the image.
        // `rank`: the first estimate of all returned that matches it (-1: none), to tell an
        // instance ranked below k from one never found.
        for (size_t j : inst) {
          int rank = -1;
          for (size_t c = 0; c < d.estimates.size() && rank < 0; ++c)
            if (o.criterion.accepts(score(d.estimates[c], g.gt[j]))) rank = static_cast<int>(c);
          const bool top1 = rank == 0, topk = rank >= 0 && static_cast<size_t>(rank) < inst.size();
          instances.push_back({{"scene", ref.scene},
                               {"image", ref.image},
                               {"obj_id", obj_id},
                               {"instance", j},
                               {"visib_fract", g.info[j].visib_fract},
                               {"top1", top1},
                               {"topk", topk},
                               {"rank", rank}});
        }
        ++n_trials;
        failures += !correct;
        time_sum += d.times.total_ms;
        if (!o.quiet)
          std::fprintf(stderr, "%s scene %d image %d obj %d: %s (%.0f ms)\n", m.c_str(), ref.scene, ref.image, obj_id,
                       correct ? "correct" : (d.estimates.empty() ? "nothing found" : "wrong"), d.times.total_ms);
      }
    }
    std::printf("%-6s failure rate %.3f over %d trials (%zu images), %.0f ms per detection\n", m.c_str(),
                n_trials ? double(failures) / n_trials : 0.0, n_trials, images.size(),
                n_trials ? time_sum / n_trials : 0.0);
    std::fflush(stdout);
    methods[m] = {{"setup_s", det->setup_seconds()}, {"trials", trials}, {"instances", instances}};

    if (m == "fdcm" && o.all_types) {
      // Best pick over all part types at once: the daemon's cycle.
      json picks = json::array();
      for (size_t k = 0; k < images.size(); ++k) {
        const ImageRef& ref = images[k];
        if (o.floor_per_scene) det->set_floor_mm(floor_of(ref.scene));
        det->detect(dataset.frames(ref.scene, ref.image), 0, d);
        bool correct = false;
        if (!d.estimates.empty())
          for (const auto& gp : gts[k].gt)
            if (gp.obj_id == d.estimates[0].obj_id) correct = correct || o.criterion.accepts(score(d.estimates[0], gp));
        json pick = {{"scene", ref.scene},
                     {"image", ref.image},
                     {"found", !d.estimates.empty()},
                     {"obj_id", d.estimates.empty() ? 0 : d.estimates[0].obj_id},
                     {"correct", correct},
                     {"times", times_json(d.times)},
                     {"escalated", d.escalated}};
        if (!d.estimates.empty()) pick["score"] = d.estimates[0].score;
        // The cell's pick (without grasp features when none are given: both settings then agree).
        std::tie(pick["cell"], pick["candidates"]) = cell_picks(ref, gts[k], d);
        if (o.timing_repeats > 1) pick["times_best"] = repeat_timing(*det, dataset.frames(ref.scene, ref.image), 0, d);
        picks.push_back(pick);
      }
      out["all_types"] = picks;
    }
  }
  out["methods"] = methods;
  out["timing_repeats"] = o.timing_repeats;

  const fs::path tmp = o.out.string() + ".tmp";
  {
    std::ofstream f(tmp);
    if (!f) throw std::runtime_error(tmp.string() + ": cannot create");
    f << out.dump(1) << "\n";
    if (!f) throw std::runtime_error(tmp.string() + ": write failed");
  }
  fs::rename(tmp, o.out);
  std::printf("wrote %s\n", o.out.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    EvalCommand command;
    if (const auto code = parse_eval_command_line(argc, argv, MFC_SOURCE_DIR, command)) return *code;
    if (command.name == "detect") return run_detect(command.detect);
    if (command.name == "edges") return run_edge_eval(command.edges);
    return run_refine_eval(command.refine);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mfc-eval: %s\n", e.what());
    return 1;
  }
}
