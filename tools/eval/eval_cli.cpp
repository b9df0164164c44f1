// mfc-eval's command line: the detect and refine commands, their options and their checks, on
// tools/common/cli.hpp. Every refusal names the option; usage errors exit 2 before anything is read.
#include <sstream>

#include "tools/common/cli.hpp"
#include "tools/eval/eval_options.hpp"

namespace mfcd::eval {

namespace {

using mfcd::tools::add_converted;
using mfcd::tools::add_double;
using mfcd::tools::add_int;
using mfcd::tools::UsageError;

// --distances LIST: comma-separated positive distances (mm), appended (the option may be repeated).
CLI::Option* add_distances(CLI::App& cmd, std::vector<double>& into, const std::string& help) {
  return cmd
      .add_option_function<std::vector<std::string>>(
          "--distances",
          [&into](const std::vector<std::string>& lists) {
            for (const std::string& list : lists) {
              std::stringstream ss(list);
              for (std::string d; std::getline(ss, d, ',');) {
                into.push_back(mfcd::tools::parse_double("--distances", d));
                if (!(into.back() > 0)) throw UsageError("--distances: '" + d + "' is not a positive distance");
              }
            }
          },
          help)
      ->allow_extra_args(false)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll)
      ->type_name("LIST");
}

std::vector<std::string> parse_methods(const std::string&, const std::string& list) {
  std::vector<std::string> methods;
  std::stringstream ss(list);
  for (std::string m; std::getline(ss, m, ',');) {
    if (m != "fdcm" && m != "fdcm-rounds" && m != "fdcm-search" && m != "ocm" && m != "cm" && m != "line2d")
      throw UsageError("--methods: unknown method '" + m +
                       "' (known: fdcm, fdcm-rounds, fdcm-search, ocm, cm, line2d)");
    methods.push_back(m);
  }
  if (methods.empty()) throw UsageError("--methods needs at least one method");
  return methods;
}

// --set KEY=VALUE (repeatable): each is refused here, before any dataset is read.
CLI::Option* add_settings(CLI::App& cmd, std::vector<std::string>& into, const std::string& help) {
  return mfcd::tools::add_converted_list(
             cmd, "--set", into,
             [](const std::string&, const std::string& v) {
               try {
                 vision::PipelineConfig probe;
                 apply_eval_setting(probe, v);
               } catch (const std::invalid_argument& e) {
                 throw UsageError(std::string("--set: ") + e.what());
               }
               return v;
             },
             help)
      ->type_name("KEY=VALUE");
}

// How the pipeline methods run: refinement, the bin floor, parameters, timing.
void add_detect_pipeline_options(CLI::App& cmd, DetectEvalOptions& o) {
  add_converted(
      cmd, "--refine-candidates", o.refine_candidates,
      [](const std::string& opt, const std::string& v) {
        const int n = mfcd::tools::parse_int(opt, v);
        if (n < 0) throw UsageError("--refine-candidates must be >= 0");
        return n;
      },
      "candidates the pipeline refines (1 view); 0 = coarse poses only\n"
      "(default: the pipeline's default, PipelineConfig::refine_candidates)")
      ->type_name("N");
  add_converted(
      cmd, "--floor", o.floor_mm,
      [&o](const std::string& opt, const std::string& v) {
        o.floor_per_scene = v == "scene";
        const double mm = o.floor_per_scene ? 0 : mfcd::tools::parse_double(opt, v);
        if (!(mm >= 0)) throw UsageError("--floor must be >= 0 (0: not known) or scene");
        return mm;
      },
      "the bin floor's distance from the camera along the optical axis, as the\n"
      "cell knows it (mfc-sim: the camera's working distance). The pipeline\n"
      "drops fitted poses below it and fits the best few just above it again\n"
      "from it; unfitted poses (baselines, LINE-2D) below it are slid onto it\n"
      "(PipelineConfig::floor). `scene`: each scene's own, from the\n"
      "floor_distance_mm of its scene_render.json (the generalization bench's\n"
      "scenes, whose bins stand at different heights). Default 0: not known")
      ->type_name("MM|scene");
  add_settings(cmd, o.pipeline_settings,
               "a pipeline parameter for the pipeline methods (repeatable; the keys of\n"
               "docs/configuration.md's vision table, trace, floor_distance_mm), e.g.\n"
               "--set view_stride=2; an unknown key lists the keys");
  cmd.add_flag("--all-types", o.all_types, "also run FDCM once per image over all part types (best pick; timing)");
  cmd.add_flag("--shading", o.shading,
               "also compare the flashes' shares of light at each candidate's and each true\n"
               "pose with the images' (vision/pose/shading_check.hpp): shading_error, shading_pixels");
  add_int(cmd, "--timing-repeats", o.timing_repeats,
          "run every fdcm detection (and --all-types run) N times on its image (1-10,\n"
          "default 1): its trial keeps the first run's result and times, and adds\n"
          "\"times_best\", the stage times of the run with the smallest total (the\n"
          "machine is shared: the fastest of a few runs has the least of the other\n"
          "tenants' interference in it; docs/results.md)");
}

// The dataset, the templates, what is written and which methods run.
void add_detect_inputs(CLI::App& cmd, DetectEvalOptions& o) {
  cmd.add_option("--dataset", o.dataset, "BOP-layout dataset with flash images (mfc-sim, docs/datasets.md)")
      ->type_name("DIR");
  cmd.add_option("--split", o.split, "split folder (default test)")->type_name("NAME");
  cmd.add_option("--camera", o.camera,
                 "camera YAML whose flash positions are used where the dataset's\n"
                 "scene_camera.json gives none (a standard BOP dataset)")
      ->type_name("FILE");
  cmd.add_flag("--model-symmetries", o.model_symmetries,
               "score with the symmetries of the dataset's models_info.json (BOP's\n"
               "symmetries_discrete and symmetries_continuous, the latter every 1 deg)\n"
               "instead of the parts table's");
  cmd.add_option("--templates", o.templates, "folder with <name>.tdb per part (mfc-teach; <build>/templates)")
      ->type_name("DIR");
  cmd.add_option("--parts", o.parts,
                 "parts table name,obj_id,symmetry[,views_symmetry[,views]] (default\n"
                 "config/parts/parts.csv)")
      ->type_name("FILE");
  cmd.add_option("--out", o.out, "JSON to write")->type_name("FILE");
  add_converted(cmd, "--methods", o.methods, parse_methods,
                "comma-separated: fdcm, fdcm-rounds, fdcm-search, ocm, cm, line2d (default\n"
                "fdcm,ocm,cm); fdcm-search = FDCM without the hypothesis fit (ranked by the\n"
                "search cost, as CM and OCM are: the matching costs compared on equal\n"
                "terms); fdcm-rounds = FDCM with two search rounds (search_rounds=2: the\n"
                "second searches again without the best candidate's edges)")
      ->type_name("LIST");
  add_int(cmd, "--max-images", o.max_images, "only the first N images (default all)");
  add_int(cmd, "--threads", o.threads, "threads of every stage of a detection (default: all cores)");
  add_distances(cmd, o.distances_mm,
                "part distances (mm) the pipeline searches, e.g. 292,282,272,262: the\n"
                "templates' scale is searched for each (default: the templates' own)");
  add_detect_pipeline_options(cmd, o);
}

// The LINE-2D peer, the criterion, the overlays and the cell's pick.
void add_detect_scoring(CLI::App& cmd, DetectEvalOptions& o) {
  add_double(cmd, "--line2d-step", o.line2d.inplane_step_deg, "LINE-2D in-plane rotation step (default 15)")
      ->type_name("DEG");
  add_int(cmd, "--line2d-view-stride", o.line2d.view_stride, "LINE-2D: train every S-th template view (default 1)")
      ->type_name("S");
  add_double(cmd, "--max-position", o.criterion.max_position_mm, "criterion (default 5)")->type_name("MM");
  add_double(cmd, "--max-rotation", o.criterion.max_rotation_deg, "criterion (default 10)")->type_name("DEG");
  cmd.add_option("--overlay", o.overlay,
                 "for every failed trial of a pipeline method, a PNG in DIR: the depth\n"
                 "edges (grey) with the template points of every true instance of the\n"
                 "type (green), the best estimate (red) and, with --set trace=1, the\n"
                 "fitted hypothesis nearest the truth (yellow); points with no image\n"
                 "edge within 1 px are drawn dim")
      ->type_name("DIR");
  cmd.add_option("--grasp-features", o.grasp_features,
                 "the parts' grasp features (config/parts/grasp-features.csv): every estimate\n"
                 "gets the pipeline's grasp visibility (PoseCandidate::grasp_visibility), every\n"
                 "true instance the estimate at its pose beside the rendered truth, and with\n"
                 "--all-types every image the cell's pick (motion::choose_pick, config/sim.yaml's\n"
                 "weights) without and with the grasp features")
      ->type_name("FILE");
  cmd.add_option_function<std::string>(
         "--pick-grasp",
         [&o](const std::string& v) {
           const auto comma = v.find(',');
           if (comma == std::string::npos) throw UsageError("--pick-grasp takes W,V (weight, minimum visibility)");
           o.grasp_weight = mfcd::tools::parse_double("--pick-grasp", v.substr(0, comma));
           o.min_grasp_visibility = mfcd::tools::parse_double("--pick-grasp", v.substr(comma + 1));
         },
         "the cell's pick with grasp features: weight_grasp W and min_grasp_visibility V\n"
         "(default 0.5,0.3, config/sim.yaml's)")
      ->type_name("W,V");
  add_double(cmd, "--pick-min-score", o.pick_min_score,
             "the cell's pick.min_score (default motion::PickChoiceConfig's, the daemon's)")
      ->type_name("S");
  cmd.add_flag("--pick-ambiguous", o.pick_ambiguous,
               "let the cell's pick take ambiguous candidates (default: passed over,\n"
               "pick.skip_ambiguous)");
  cmd.add_flag("--quiet", o.quiet, "no per-image lines");
}

void add_refine_options(CLI::App& cmd, RefineEvalOptions& o) {
  cmd.add_option("--templates", o.templates, "as for detect")->type_name("DIR");
  cmd.add_option("--parts", o.parts, "as for detect")->type_name("FILE");
  cmd.add_option("--out", o.out, "JSON to write")->type_name("FILE");
  add_distances(cmd, o.distances_mm, "as for detect");
  cmd.add_flag("--quiet", o.quiet, "no per-part lines");
  cmd.add_option("--camera", o.camera, "camera YAML (default config/camera-sim.yaml)")->type_name("FILE");
  add_int(cmd, "--trials", o.trials_per_part, "random poses per part (default 10)");
  add_converted(
      cmd, "--seed", o.seed,
      [](const std::string& opt, const std::string& v) {
        return static_cast<unsigned>(mfcd::tools::parse_int(opt, v));
      },
      "(default 1)")
      ->type_name("N");
  add_double(cmd, "--shift", o.side_shift_mm, "sideways shift of the second camera (default 80)")->type_name("MM");
}

// What the options must satisfy together; throws UsageError naming the option.
void check_detect(DetectEvalOptions& o) {
  o.line2d.distances_mm = o.distances_mm;
  o.line2d.floor.distance_mm = o.floor_mm;
  // First, so that a --set floor_distance_mm of an experiment still overrides it.
  if (o.floor_mm > 0)
    o.pipeline_settings.insert(o.pipeline_settings.begin(), "floor_distance_mm=" + std::to_string(o.floor_mm));
  if (o.dataset.empty()) throw UsageError("--dataset is required");
  if (o.templates.empty()) throw UsageError("--templates is required");
  if (o.out.empty()) throw UsageError("--out is required");
  if (o.max_images < 0) throw UsageError("--max-images must be >= 0");
  if (!(o.pick_min_score >= 0 && o.pick_min_score <= 1)) throw UsageError("--pick-min-score must be in 0..1");
  if (!(o.grasp_weight >= 0 && o.grasp_weight <= 100) || !(o.min_grasp_visibility >= 0 && o.min_grasp_visibility <= 1))
    throw UsageError("--pick-grasp: the weight must be in 0..100 and the minimum visibility in 0..1");
  if (o.timing_repeats < 1 || o.timing_repeats > 10) throw UsageError("--timing-repeats must be in 1..10");
  if (!(o.line2d.inplane_step_deg > 0 && o.line2d.inplane_step_deg <= 360))
    throw UsageError("--line2d-step must be in (0, 360]");
  if (o.line2d.view_stride < 1) throw UsageError("--line2d-view-stride must be >= 1");
  if (!(o.criterion.max_position_mm > 0) || !(o.criterion.max_rotation_deg > 0))
    throw UsageError("--max-position and --max-rotation must be positive");
}

void add_edge_options(CLI::App& cmd, EdgeEvalOptions& o) {
  cmd.add_option("--dataset", o.dataset, "BOP-layout dataset with flash/, ambient/ and depth/ images")
      ->type_name("DIR");
  cmd.add_option("--split", o.split, "split folder (default test)")->type_name("NAME");
  cmd.add_option("--out", o.out, "JSON to write")->type_name("FILE");
  cmd.add_option("--overlay", o.overlay,
                 "a PNG per image: truth jumps grey, creases blue, detected pixels on them green, others red")
      ->type_name("DIR");
  add_int(cmd, "--max-images", o.max_images, "images evaluated, in scene order (default 0: all)");
  add_double(cmd, "--min-jump", o.min_jump_mm, "mm a depth jump needs (default 4)");
  add_double(cmd, "--crease", o.crease_deg, "degrees a crease's normal turns (default 30)");
  add_double(cmd, "--tolerance", o.tolerance_px, "px between a detected and a truth pixel (default 1)");
  add_settings(cmd, o.pipeline_settings,
               "a pipeline parameter (repeatable); the edges_* keys are the ones the extractor reads");
  cmd.add_flag("--quiet", o.quiet, "no per-image lines");
}

void check_edges(const EdgeEvalOptions& o) {
  if (o.dataset.empty()) throw UsageError("--dataset is required");
  if (o.out.empty()) throw UsageError("--out is required");
  if (o.max_images < 0) throw UsageError("--max-images must be >= 0");
  if (!(o.min_jump_mm > 0) || !(o.crease_deg > 0) || !(o.tolerance_px >= 0))
    throw UsageError("--min-jump and --crease must be positive, --tolerance >= 0");
}

void check_refine(const RefineEvalOptions& o) {
  if (o.templates.empty()) throw UsageError("--templates is required");
  if (o.out.empty()) throw UsageError("--out is required");
  if (o.trials_per_part < 1) throw UsageError("--trials must be >= 1");
  if (!std::filesystem::is_directory(o.templates))
    throw std::runtime_error(o.templates.string() + ": no such templates folder");
}

}  // namespace

std::optional<int> parse_eval_command_line(int argc, char** argv, const std::filesystem::path& source_dir,
                                           EvalCommand& command) {
  CLI::App app{
      "The paper's evaluation (Sec. 5.1.1) on a BOP-layout dataset of simulated bins; tools/eval/report.py\n"
      "turns its JSON into docs/results.md.",
      "mfc-eval"};
  mfcd::tools::init_app(app);
  command.detect.parts = command.refine.parts = source_dir / "config/parts/parts.csv";
  command.refine.camera = source_dir / "config/camera-sim.yaml";
  CLI::App* detect = app.add_subcommand(
      "detect",
      "Table 1 (failure rate and time per part type, CM / OCM / FDCM / LINE-2D), Fig. 13 (detection rate vs\n"
      "occlusion) and the per-stage timing, as JSON. For every image and every part type present in it, runs\n"
      "each method for that type (the recipe) and scores its best estimate against every ground-truth\n"
      "instance of the type (correct when it matches any: position <= 5 mm and rotation angle <= 10 deg,\n"
      "symmetry-aware). Needs --dataset, --templates and --out.");
  add_detect_inputs(*detect, command.detect);
  add_detect_scoring(*detect, command.detect);
  CLI::App* refine = app.add_subcommand(
      "refine",
      "Table 2 (1-view vs 2-view refinement): each part alone in random poses (random orientation, centre\n"
      "within +-25, +-20 mm of the axis at 284-300 mm) over a floor, coarse pose from the pipeline (view 0),\n"
      "then refined with view 0 alone and with views 0 and 1 (camera 1 shifted sideways and turned to look\n"
      "at the part). Needs the multi-view refiner (vision/pose/pose_refiner.hpp) in the build, --templates\n"
      "and --out.");
  add_refine_options(*refine, command.refine);
  CLI::App* edges = app.add_subcommand(
      "edges",
      "The depth-edge extractor on a rendered dataset against each image's ground-truth depth: precision\n"
      "against depth jumps and creases, recall against jumps, per image and pooled. Needs --dataset and --out.");
  add_edge_options(*edges, command.edges);
  app.require_subcommand(1);
  // `mfc-eval help` is `mfc-eval --help`, as it always was.
  std::vector<const char*> args(argv, argv + argc);
  if (args.size() > 1 && std::string(args[1]) == "help") args[1] = "--help";
  if (const auto code = mfcd::tools::parse(app, static_cast<int>(args.size()), args.data())) return code;
  command.name = app.get_subcommands().front()->get_name();
  try {
    if (command.name == "detect")
      check_detect(command.detect);
    else if (command.name == "edges")
      check_edges(command.edges);
    else
      check_refine(command.refine);
  } catch (const UsageError& e) {
    return mfcd::tools::usage_error(app, e.what());
  }
  return std::nullopt;
}

}  // namespace mfcd::eval
