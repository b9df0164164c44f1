#pragma once
// mfc-eval's command line (eval_cli.cpp): `detect` (Table 1, Fig. 13, timing) and `refine`
// (Table 2, refine_eval.hpp), with the options `mfc-eval detect --help` lists.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "motion/pick_choice.hpp"
#include "tools/eval/detectors.hpp"
#include "tools/eval/edge_eval.hpp"
#include "tools/eval/pose_error.hpp"
#include "tools/eval/refine_eval.hpp"

namespace mfcd::eval {

struct DetectEvalOptions {
  std::filesystem::path dataset, templates, parts, out, overlay;  // parts: default config/parts/parts.csv
  std::filesystem::path camera;   // --camera: flash positions for a dataset that lacks them
  bool model_symmetries = false;  // --model-symmetries
  std::string split = "test";
  std::vector<std::string> methods = {"fdcm", "ocm", "cm"};
  int max_images = 0, threads = 0, refine_candidates = -1;
  std::filesystem::path grasp_features;  // --grasp-features: the parts' grasp features (pick evaluation)
  double grasp_weight = 0.5, min_grasp_visibility = 0.3;         // --pick-grasp W,V (config/sim.yaml's)
  double pick_min_score = motion::PickChoiceConfig{}.min_score;  // --pick-min-score
  bool pick_ambiguous = false;                                   // --pick-ambiguous
  int timing_repeats = 1;                                        // --timing-repeats
  double floor_mm = 0;                                           // --floor
  bool floor_per_scene = false;                                  // --floor scene
  std::vector<double> distances_mm;
  std::vector<std::string> pipeline_settings;  // --set KEY=VALUE, applied in order; --floor's first
  bool all_types = false, quiet = false;
  bool shading = false;  // --shading: each candidate's and each true pose's ShadingAgreement
  Line2dOptions line2d;
  Criterion criterion;
};

// The command the command line asks for and its options.
struct EvalCommand {
  std::string name;  // "detect", "refine" or "edges"
  DetectEvalOptions detect;
  RefineEvalOptions refine;
  EdgeEvalOptions edges;
};

// Parses and checks mfc-eval's command line into `command`. Returns the exit status when the
// program ends here (0 after --help or --version, 2 after a usage error, reported on stderr);
// nullopt to run the command. `source_dir` holds config/ (the default parts table and camera).
std::optional<int> parse_eval_command_line(int argc, char** argv, const std::filesystem::path& source_dir,
                                           EvalCommand& command);

}  // namespace mfcd::eval
