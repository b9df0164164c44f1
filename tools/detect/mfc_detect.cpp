// mfc-detect: the full vision pipeline (depth edges from the flash images -> lines -> DT3/IDT3 ->
// line search over every template -> coarse pose -> refinement) on every image of a BOP-layout
// dataset with multi-flash images; writes the BOP results CSV
//   scene_id,im_id,obj_id,score,R,t,time
// with R row-major (9 values) and t in mm (3 values), space-separated, and time the wall time of
// the image's detection in seconds (the same for every estimate of the image, as BOP asks);
// vision/dataset/bop_results.hpp formats it. Named METHOD_DATASET-SPLIT.csv, the BOP toolkit
// scores it (docs/datasets.md, "Scoring with the BOP toolkit").
#include "tools/common/cli_numbers.hpp"
#include "vision/dataset/bop_dataset.hpp"
#include "vision/dataset/bop_results.hpp"
#include "vision/pipeline/bin_picking_pipeline.hpp"

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

void usage(std::FILE* to) {
  std::fprintf(to,
               "usage: mfc-detect --dataset DIR --templates A.tdb [B.tdb ...] --out results.csv [options]\n"
               "  --dataset DIR        BOP-layout dataset with flash/ and ambient/ images (docs/datasets.md)\n"
               "  --split NAME         split folder (default test)\n"
               "  --camera FILE        camera YAML (docs/camera.md) whose flash positions are used where the\n"
               "                       dataset's scene_camera.json gives none (a standard BOP dataset)\n"
               "  --templates F...     template databases (mfc-teach); each carries its part's obj_id\n"
               "  --out FILE           BOP results CSV to write; for the BOP toolkit name it METHOD_DATASET-SPLIT.csv\n"
               "                       (e.g. mfcdetect_mfcsim-test.csv: no '_' in METHOD, no '-' or '_' in DATASET)\n"
               "  --views N            views used by the refinement (default 1; more need camera poses)\n"
               "  --max-per-image N    estimates kept per image (default 10)\n"
               "  --max-cost PX        search threshold, mean directional chamfer px (default 10)\n"
               "  --floor MM           the bin floor's distance from the camera (along the optical axis): poses\n"
               "                       below it are dropped, the best few just above it also fitted from it\n"
               "                       (PipelineConfig::floor; default 0: not known)\n"
               "  --search-rounds N    search rounds per image, 1-4 (default 2): a later round searches again\n"
               "                       without the edges of the best estimates so far, so that the other\n"
               "                       instances of a type are found too (PipelineConfig::search_rounds)\n"
               "  --scene ID           only this scene (repeatable)\n"
               "  --threads N          threads of every stage of a detection (default: all cores)\n"
               "  --quiet              no per-image lines\n");
}


}  // namespace

int main(int argc, char** argv) {
  fs::path dataset_dir, out, camera_file;
  std::string split = "test";
  std::vector<fs::path> templates;
  std::vector<int> only_scenes;
  int views = 1, max_per_image = 10, threads = 0, search_rounds = 2;
  double max_cost = PipelineConfig{}.max_cost_px, floor_mm = 0;
  bool quiet = false;
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      auto value = [&]() -> std::string {
        if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
        return argv[++i];
      };
      if (a == "-h" || a == "--help") {
        usage(stdout);
        return 0;
      } else if (a == "--dataset") dataset_dir = value();
      else if (a == "--split") split = value();
      else if (a == "--camera") camera_file = value();
      else if (a == "--out") out = value();
      else if (a == "--views") views = mfcd::tools::parse_int(a, value());
      else if (a == "--max-per-image") max_per_image = mfcd::tools::parse_int(a, value());
      else if (a == "--threads") threads = mfcd::tools::parse_int(a, value());
      else if (a == "--scene") only_scenes.push_back(mfcd::tools::parse_int(a, value()));
      else if (a == "--max-cost") max_cost = mfcd::tools::parse_double(a, value());
      else if (a == "--floor") floor_mm = mfcd::tools::parse_double(a, value());
      else if (a == "--search-rounds") search_rounds = mfcd::tools::parse_int(a, value());
      else if (a == "--quiet") quiet = true;
      else if (a == "--templates") {
        while (i + 1 < argc && argv[i + 1][0] != '-') templates.emplace_back(argv[++i]);
        if (templates.empty()) throw std::invalid_argument("--templates needs at least one file");
      } else throw std::invalid_argument("unknown argument " + a);
    }
    if (dataset_dir.empty() || out.empty() || templates.empty()) {
      usage(stderr);
      return 2;
    }
    if (views < 1) throw std::invalid_argument("--views must be >= 1");
    if (views > 1)
      throw std::invalid_argument("--views " + std::to_string(views) +
                                  ": the dataset gives no camera poses between its images (cam_R_w2c/cam_t_w2c); "
                                  "multi-view refinement is measured by mfc-eval");
    if (max_per_image < 1) throw std::invalid_argument("--max-per-image must be >= 1");
    if (search_rounds < 1 || search_rounds > PipelineConfig::kMaxSearchRounds)
      throw std::invalid_argument("--search-rounds must be 1.." + std::to_string(PipelineConfig::kMaxSearchRounds));

    BopCameraDefaults defaults;
    if (!camera_file.empty()) defaults = {load_camera_config(camera_file).flashes.positions_mm, camera_file.string()};
    const BopDataset dataset(dataset_dir, split, defaults);
    std::vector<int> scenes = dataset.scenes();
    if (!only_scenes.empty()) scenes = only_scenes;
    if (scenes.empty()) throw std::runtime_error(dataset_dir.string() + ": no scenes in split '" + split + "'");

    // One pipeline per distinct camera (datasets may change K between scenes).
    std::map<std::string, std::unique_ptr<BinPickingPipeline>> pipelines;
    PipelineConfig pc;
    pc.template_files = templates;
    pc.max_candidates = max_per_image;
    pc.max_cost_px = max_cost;
    pc.threads = threads;
    pc.floor.distance_mm = floor_mm;
    pc.search_rounds = search_rounds;

    // The toolkit takes the dataset and split from the name; other names are fine for mfcd's own tools.
    if (const auto name = parse_bop_results_name(out.string()); !name)
      std::fprintf(stderr, "mfc-detect: note: %s is not named METHOD_DATASET-SPLIT.csv; rename it before scoring it "
                   "with the BOP toolkit\n", out.filename().c_str());
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
        pipeline->process(frames, 0, t0 + std::chrono::hours(1), result);
        const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        total_s += seconds;
        ++images;
        for (const auto& c : result.candidates) {
          csv << bop_results_row({.scene_id = scene, .im_id = im, .obj_id = c.obj_id, .score = c.score,
                                  .R = c.R_m2c, .t_mm = c.t_m2c_mm, .time_s = seconds});
          ++estimates;
        }
        if (!quiet)
          std::fprintf(stderr, "scene %d image %d: %zu estimates, %.0f ms (edges %.0f, lines %.0f, dt %.0f, search %.0f, "
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
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mfc-detect: %s\n", e.what());
    return 1;
  }
}
