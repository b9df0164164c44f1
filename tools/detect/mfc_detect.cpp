// mfc-detect: the full vision pipeline (depth edges from the flash images -> lines -> DT3/IDT3 ->
// line search over every template -> coarse pose -> refinement) on every image of a BOP-layout
// dataset with multi-flash images; writes the BOP results CSV
//   scene_id,im_id,obj_id,score,R,t,time
// with R row-major (9 values) and t in mm (3 values), space-separated, and time the wall time of
// the image's detection in seconds (the same for every estimate of the image, as BOP asks);
// vision/dataset/bop_results.hpp formats it. Named METHOD_DATASET-SPLIT.csv, the BOP toolkit
// scores it (docs/datasets.md, "Scoring with the BOP toolkit"). Exit status: 0 written, 1 refused
// (dataset, templates), 2 usage.
//
// A snapshot of mfcd is such a dataset with a replay manifest (mfcd_replay.json): then the
// cycle's template files (checked by size and CRC-32), vision settings and part type are used,
// so the run gives the cycle's candidates again; options given on the command line override them.
#include "tools/common/cli.hpp"
#include "vision/dataset/bop_dataset.hpp"
#include "vision/dataset/bop_results.hpp"
#include "vision/pipeline/bin_picking_pipeline.hpp"
#include "vision/pipeline/pipeline_parameters.hpp"
#include "vision/pipeline/replay_manifest.hpp"

#include <chrono>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <string>
#include <vector>

using namespace mfcd::vision;
namespace fs = std::filesystem;

namespace {

// What the command line sets; defaults as mfc-detect has always had them.
struct Options {
  fs::path dataset_dir, out, camera_file;
  std::string split = "test";
  std::vector<fs::path> templates;
  std::vector<int> only_scenes;
  std::vector<std::string> settings;  // --set KEY=VALUE, applied last
  int views = 1, max_per_image = 10, threads = 0, search_rounds = 2;
  double max_cost = PipelineConfig{}.max_cost_px, floor_mm = 0;
  bool quiet = false;
};

void add_options(CLI::App& app, Options& o) {
  using mfcd::tools::add_double;
  using mfcd::tools::add_int;
  app.add_option("--dataset", o.dataset_dir, "BOP-layout dataset with flash/ and ambient/ images (docs/datasets.md)")
      ->required()
      ->type_name("DIR");
  app.add_option("--split", o.split, "split folder (default test)")->type_name("NAME");
  app.add_option("--camera", o.camera_file,
                 "camera YAML (docs/camera.md) whose flash positions are used where the\n"
                 "dataset's scene_camera.json gives none (a standard BOP dataset)")
      ->type_name("FILE");
  // The files after --templates up to the next option; --templates may be repeated.
  app.add_option("--templates", o.templates,
                 "template databases (mfc-teach); each carries its part's obj_id\n"
                 "(required unless the dataset is an mfcd snapshot: its mfcd_replay.json names them)")
      ->type_name("F...")
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  app.add_option("--out", o.out,
                 "BOP results CSV to write; for the BOP toolkit name it METHOD_DATASET-SPLIT.csv\n"
                 "(e.g. mfcdetect_mfcsim-test.csv: no '_' in METHOD, no '-' or '_' in DATASET)")
      ->required()
      ->type_name("FILE");
  add_int(app, "--views", o.views, "views used by the refinement (default 1; more need camera poses)");
  add_int(app, "--max-per-image", o.max_per_image, "estimates kept per image (default 10)");
  add_double(app, "--max-cost", o.max_cost, "search threshold, mean directional chamfer px (default 10)")
      ->type_name("PX");
  add_double(app, "--floor", o.floor_mm,
             "the bin floor's distance from the camera (along the optical axis): poses\n"
             "below it are dropped, the best few just above it also fitted from it\n"
             "(PipelineConfig::floor; default 0: not known)")
      ->type_name("MM");
  add_int(app, "--search-rounds", o.search_rounds,
          "search rounds per image, 1-4 (default 2): a later round searches again\n"
          "without the edges of the best estimates so far, so that the other\n"
          "instances of a type are found too (PipelineConfig::search_rounds)");
  mfcd::tools::add_converted_list(app, "--scene", o.only_scenes, mfcd::tools::parse_int, "only this scene (repeatable)")
      ->type_name("ID");
  add_int(app, "--threads", o.threads, "threads of every stage of a detection (default: all cores)");
  mfcd::tools::add_converted_list(
      app, "--set", o.settings,
      [](const std::string&, const std::string& v) {
        try {
          PipelineConfig probe;
          apply_pipeline_setting(probe, v);
        } catch (const std::invalid_argument& e) {
          throw mfcd::tools::UsageError(std::string("--set: ") + e.what());
        }
        return v;
      },
      "a pipeline parameter, KEY=VALUE (repeatable; docs/configuration.md \"vision\"), applied last")
      ->type_name("KEY=VALUE");
  app.add_flag("--quiet", o.quiet, "no per-image lines");
}

// What the options must satisfy; throws UsageError naming the option.
void check_options(const Options& o) {
  using mfcd::tools::UsageError;
  if (o.views < 1) throw UsageError("--views must be >= 1");
  if (o.views > 1)
    throw UsageError("--views " + std::to_string(o.views) +
                     ": the dataset gives no camera poses between its images (cam_R_w2c/cam_t_w2c); "
                     "multi-view refinement is measured by mfc-eval");
  if (o.max_per_image < 1) throw UsageError("--max-per-image must be >= 1");
  if (o.search_rounds < 1 || o.search_rounds > PipelineConfig::kMaxSearchRounds)
    throw UsageError("--search-rounds must be 1.." + std::to_string(PipelineConfig::kMaxSearchRounds));
}

// The pipeline's configuration: the options, or for an mfcd snapshot the cycle's own settings and
// template files with the options given on the command line over them. `obj_id` is the part type
// to look for (0: all loaded).
PipelineConfig pipeline_config(const CLI::App& app, const Options& o, const fs::path& dataset, int& obj_id) {
  PipelineConfig pc;
  const auto given = [&](const char* name) { return app.count(name) > 0; };
  const auto manifest = read_replay_manifest(dataset);
  obj_id = 0;
  if (manifest) {
    std::vector<std::string> ignored;
    pc = replay_config(*manifest, pc, ignored);  // throws when a template file differs
    obj_id = manifest->obj_id;
    std::fprintf(stderr, "mfc-detect: %s: the settings and templates of cycle %llu (mfcd %s %s)%s\n",
                 (dataset / kReplayManifestName).c_str(), static_cast<unsigned long long>(manifest->cycle),
                 manifest->version.c_str(), manifest->commit.c_str(), obj_id ? "" : ", every part type");
    for (const std::string& k : ignored)
      std::fprintf(stderr, "mfc-detect: note: parameter '%s' of the snapshot is not known to this mfc-detect\n",
                   k.c_str());
  } else if (o.templates.empty()) {
    throw mfcd::tools::UsageError("--templates is required (the dataset has no " + std::string(kReplayManifestName) +
                                  ")");
  }
  if (!manifest || !o.templates.empty()) pc.template_files = o.templates;
  if (!manifest || given("--max-per-image")) pc.max_candidates = o.max_per_image;
  if (!manifest || given("--max-cost")) pc.max_cost_px = o.max_cost;
  if (!manifest || given("--threads")) pc.threads = o.threads;
  if (!manifest || given("--floor")) pc.floor.distance_mm = o.floor_mm;
  if (!manifest || given("--search-rounds")) pc.search_rounds = o.search_rounds;
  for (const std::string& s : o.settings) apply_pipeline_setting(pc, s);
  validate_parameters(pc);
  return pc;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "The full pipeline on every image of a BOP-layout dataset with multi-flash images; writes the BOP\n"
      "results CSV (docs/datasets.md).",
      "mfc-detect"};
  mfcd::tools::init_app(app);
  Options o;
  add_options(app, o);
  if (const auto code = mfcd::tools::parse(app, argc, argv)) return *code;
  const fs::path &dataset_dir = o.dataset_dir, &out = o.out, &camera_file = o.camera_file;
  const std::string& split = o.split;
  try {
    check_options(o);
    BopCameraDefaults defaults;
    if (!camera_file.empty()) defaults = {load_camera_config(camera_file).flashes.positions_mm, camera_file.string()};
    const BopDataset dataset(dataset_dir, split, defaults);
    std::vector<int> scenes = dataset.scenes();
    if (!o.only_scenes.empty()) scenes = o.only_scenes;
    if (scenes.empty()) throw std::runtime_error(dataset_dir.string() + ": no scenes in split '" + split + "'");

    // One pipeline per distinct camera (datasets may change K between scenes).
    std::map<std::string, std::unique_ptr<BinPickingPipeline>> pipelines;
    int obj_id = 0;
    const PipelineConfig pc = pipeline_config(app, o, dataset_dir, obj_id);

    // The toolkit takes the dataset and split from the name; other names are fine for mfcd's own tools.
    if (const auto name = parse_bop_results_name(out.string()); !name)
      std::fprintf(stderr,
                   "mfc-detect: note: %s is not named METHOD_DATASET-SPLIT.csv; rename it before scoring it "
                   "with the BOP toolkit\n",
                   out.filename().c_str());
    else if (name->split != split.substr(0, split.find('_')))
      std::fprintf(stderr, "mfc-detect: note: %s names split '%s' but the estimates are of split '%s'\n",
                   out.filename().c_str(), name->split.c_str(), split.c_str());
    const fs::path tmp = out.string() + ".tmp";
    std::ofstream csv(tmp);
    if (!csv) throw std::runtime_error(tmp.string() + ": cannot create");
    csv << kBopResultsHeader << '\n';
    size_t images = 0, estimates = 0;
    double total_s = 0;
    PipelineResult result;
    for (int scene : scenes) {
      for (int im : dataset.images(scene)) {
        const BopSceneCamera bc = dataset.camera(scene, im);
        const CameraConfig cam = bc.config();
        char key[256];
        std::snprintf(key, sizeof key, "%dx%d %.6f %.6f %.6f %.6f %zu", cam.camera.image_size.width,
                      cam.camera.image_size.height, cam.camera.fx(), cam.camera.fy(), cam.camera.cx(), cam.camera.cy(),
                      cam.flashes.positions_mm.size());
        auto& pipeline = pipelines[key];
        if (!pipeline) pipeline = std::make_unique<BinPickingPipeline>(cam, pc);
        const MfcFrames frames = dataset.frames(scene, im);
        const auto t0 = std::chrono::steady_clock::now();
        pipeline->process(frames, obj_id, t0 + std::chrono::hours(1), result);
        const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        total_s += seconds;
        ++images;
        for (const auto& c : result.candidates) {
          csv << bop_results_row({.scene_id = scene,
                                  .im_id = im,
                                  .obj_id = c.obj_id,
                                  .score = c.score,
                                  .R = c.R_m2c,
                                  .t_mm = c.t_m2c_mm,
                                  .time_s = seconds});
          ++estimates;
        }
        if (!o.quiet)
          std::fprintf(stderr,
                       "scene %d image %d: %zu estimates, %.0f ms (edges %.0f, lines %.0f, dt %.0f, search %.0f, "
                       "pose %.0f, refine %.0f)\n",
                       scene, im, result.candidates.size(), seconds * 1e3, result.times.edges_ms, result.times.lines_ms,
                       result.times.distance_ms, result.times.search_ms, result.times.pose_ms, result.times.refine_ms);
      }
    }
    csv.close();
    if (!csv) throw std::runtime_error(tmp.string() + ": write failed");
    fs::rename(tmp, out);
    std::printf("%s: %zu estimates for %zu images, %.0f ms per image on average\n", out.c_str(), estimates, images,
                images ? total_s * 1e3 / images : 0.0);
    return 0;
  } catch (const mfcd::tools::UsageError& e) {
    return mfcd::tools::usage_error(app, e.what());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mfc-detect: %s\n", e.what());
    return 1;
  }
}
