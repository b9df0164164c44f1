// vision/dataset BopDataset on a dataset tree with one scene (docs/datasets.md). The input's
// first byte picks the JSON file the rest of the input replaces (byte % 5: models_info.json,
// camera.json, scene_camera.json, scene_gt.json, scene_gt_info.json; the others keep a valid
// default) and, by byte / 5, whether camera.json is left out (bit 0) and whether the reader gets
// default flash positions (bit 1). Every accessor is run over every image the scene lists.

#include "vision/dataset/bop_dataset.hpp"
#include "fuzz/fuzz_support.hpp"

#include <array>
#include <stdexcept>
#include <string>

namespace {

namespace fs = std::filesystem;

// A valid one-image dataset: what each file holds unless the input replaces it.
const std::array<std::pair<const char*, const char*>, 5> kFiles = {{
    {"models/models_info.json",
     R"({"1": {"diameter": 50.0, "min_x": -20.0, "min_y": -15.0, "min_z": -10.0, "size_x": 40.0, "size_y": 30.0,
        "size_z": 20.0, "symmetries_discrete": [[-1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]]},
        "2": {"diameter": 30.0, "min_x": -10.0, "min_y": -10.0, "min_z": 0.0, "size_x": 20.0, "size_y": 20.0,
        "size_z": 8.0, "symmetries_continuous": [{"axis": [0, 0, 1], "offset": [0, 0, 0]}]}})"},
    {"camera.json", R"({"cx": 319.5, "cy": 239.5, "fx": 1100.0, "fy": 1100.0, "width": 640, "height": 480,
        "depth_scale": 0.1})"},
    {"test/000000/scene_camera.json",
     R"({"0": {"cam_K": [1100.0, 0.0, 319.5, 0.0, 1100.0, 239.5, 0.0, 0.0, 1.0], "depth_scale": 0.1, "width": 640,
        "height": 480, "flash_positions_mm": [[40, 0, 0], [28.3, 28.3, 0], [0, 40, 0], [-28.3, 28.3, 0],
        [-40, 0, 0], [-28.3, -28.3, 0], [0, -40, 0], [28.3, -28.3, 0]], "working_distance_mm": 300.0},
        "1": {"cam_K": [1100.0, 0.0, 319.5, 0.0, 1100.0, 239.5, 0.0, 0.0, 1.0]}})"},
    {"test/000000/scene_gt.json",
     R"({"0": [{"obj_id": 1, "cam_R_m2c": [1, 0, 0, 0, 1, 0, 0, 0, 1], "cam_t_m2c": [0, 0, 300]}], "1": []})"},
    {"test/000000/scene_gt_info.json",
     R"({"0": [{"bbox_obj": [10, 20, 30, 40], "bbox_visib": [12, 22, 20, 30], "px_count_all": 1200,
        "px_count_valid": 1200, "px_count_visib": 600, "visib_fract": 0.5}], "1": []})"},
}};

const fs::path& root() {
  static const fs::path r = [] {
    const fs::path d = mfcd::fuzz::scratch_dir() / "dataset";
    fs::create_directories(d / "models");
    fs::create_directories(d / "test" / "000000");
    return d;
  }();
  return r;
}

void exercise(const mfcd::vision::BopDataset& ds) {
  for (const auto& [id, info] : ds.models_info()) {
    (void)info;
    try {
      ds.model_path(id);  // no model files in the tree: refused naming the file
    } catch (const std::runtime_error&) {
    }
  }
  for (int scene : ds.scenes())
    for (int image : ds.images(scene)) {
      try {
        const mfcd::vision::BopSceneCamera camera = ds.camera(scene, image);
        mfcd::vision::validate_camera_config(camera.config(), "scene_camera.json");
      } catch (const std::runtime_error&) {
      }
      try {
        ds.ground_truth(scene, image);
      } catch (const std::runtime_error&) {
      }
      try {
        ds.ground_truth_info(scene, image);
      } catch (const std::runtime_error&) {
      }
      try {
        ds.frames(scene, image);  // no images in the tree: refused naming the first missing one
      } catch (const std::runtime_error&) {
      }
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const size_t target = data[0] % kFiles.size();
  const unsigned flags = data[0] / kFiles.size();
  for (size_t i = 0; i < kFiles.size(); ++i) {
    const fs::path file = root() / kFiles[i].first;
    if (i == target)
      mfcd::fuzz::write_file(file, data + 1, size - 1);
    else if (i == 1 && (flags & 1))
      fs::remove(file);
    else
      mfcd::fuzz::write_file(file, kFiles[i].second);
  }
  mfcd::vision::BopCameraDefaults defaults;
  if (flags & 2) defaults = {{{40, 0, 0}, {0, 40, 0}, {-40, 0, 0}, {0, -40, 0}}, "fuzz defaults"};
  try {
    const mfcd::vision::BopDataset ds(root(), "test", defaults);
    exercise(ds);
  } catch (const std::runtime_error&) {
    // documented: the file (and key) and the reason named
  }
  return 0;
}
