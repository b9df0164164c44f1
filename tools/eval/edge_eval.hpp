#pragma once
// mfc-eval edges: how the depth-edge extractor (vision/edges/depth_edges.hpp) does on a
// rendered dataset, against the edges its ground-truth depth holds: precision against depth
// jumps and creases, recall against jumps, per image and pooled over the images.
#include <filesystem>
#include <string>
#include <vector>

namespace mfcd::eval {

struct EdgeEvalOptions {
  std::filesystem::path dataset, out, overlay;  // overlay: a PNG per image when not empty
  std::string split = "test";
  int max_images = 0;                          // 0 = every image
  double min_jump_mm = 4;                      // a depth jump: the far side this much farther, mm
  double crease_deg = 30;                      // a crease: the surface normal turning this much, degrees
  double tolerance_px = 1;                     // a detected pixel this near a truth pixel is right
  std::vector<std::string> pipeline_settings;  // --set KEY=VALUE: the edges_* keys matter here
  bool quiet = false;
};

int run_edge_eval(const EdgeEvalOptions& options);

}  // namespace mfcd::eval
