#pragma once
// Table 2 of the paper: 1-view vs 2-view pose refinement, one part at a time in random poses.
// Built only when the multi-view refiner (vision/pose/pose_refiner.hpp) is in the tree.

#include <filesystem>
#include <string>
#include <vector>

namespace mfcd::eval {

struct RefineEvalOptions {
  std::filesystem::path templates, parts, camera, out;
  int trials_per_part = 10;
  unsigned seed = 1;
  double side_shift_mm = 80;  // second camera: moved sideways by this, turned to look at the part
  std::vector<double> distances_mm;
  bool quiet = false;
};

// True when this build has the refiner (else run_refine_eval throws, naming what is missing).
bool refine_eval_available();
int run_refine_eval(const RefineEvalOptions& options);

}  // namespace mfcd::eval
