// What `mfcd-ctl calibrate apply` reports after writing new intrinsics: the recipes whose template
// files the new camera invalidates (invalidated_recipes, daemon/calibration.hpp), with the reason.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "daemon/calibration.hpp"
#include "vision/camera/camera.hpp"

using namespace mfcd::daemon;
namespace fs = std::filesystem;

namespace {

RecipeConfig recipe(int id, const std::string& part, std::optional<fs::path> templates) {
  RecipeConfig r;
  r.id = id;
  r.part = part;
  r.templates = std::move(templates);
  return r;
}

}  // namespace

TEST(CalibrationApply, NamesTheRecipesWhoseTemplatesTheNewCameraInvalidates) {
  const fs::path tnut = fs::path(MFC_BINARY_DIR) / "templates" / "tnut.tdb";
  const fs::path knob = fs::path(MFC_BINARY_DIR) / "templates" / "knob.tdb";
  if (!fs::exists(tnut) || !fs::exists(knob)) GTEST_SKIP() << "no taught templates in " << tnut.parent_path();
  const fs::path dir = fs::temp_directory_path() / ("mfcd-calibration-apply-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::vector<RecipeConfig> recipes = {recipe(1, "tnut", tnut), recipe(2, "any", std::nullopt),
                                             recipe(3, "knob", knob), recipe(4, "gone", dir / "missing.tdb")};

  // The camera the templates were taught with: only the missing file is reported.
  mfcd::vision::CameraConfig camera = mfcd::vision::load_camera_config(MFC_SOURCE_DIR "/config/camera-sim.yaml");
  const fs::path same = dir / "same.yaml";
  mfcd::vision::save_camera_config(camera, same);
  nlohmann::json out = invalidated_recipes(same, recipes);
  ASSERT_EQ(out.size(), 1u) << out.dump();
  EXPECT_EQ(out[0]["recipe"], 4);
  EXPECT_NE(out[0]["why"].get<std::string>().find("missing.tdb"), std::string::npos) << out.dump();

  // New intrinsics: fx 1% longer invalidates both taught recipes, each with the reason.
  camera.camera.K(0, 0) *= 1.01;
  camera.camera.distortion = {-0.1, 0.02, 0, 0, 0};
  const fs::path changed = dir / "changed.yaml";
  mfcd::vision::save_camera_config(camera, changed);
  out = invalidated_recipes(changed, recipes);
  ASSERT_EQ(out.size(), 3u) << out.dump();
  EXPECT_EQ(out[0]["recipe"], 1);
  EXPECT_EQ(out[0]["part"], "tnut");
  EXPECT_EQ(out[0]["templates"], tnut.string());
  EXPECT_NE(out[0]["why"].get<std::string>().find("built for another camera (fx"), std::string::npos) << out.dump();
  EXPECT_EQ(out[1]["recipe"], 3);
  EXPECT_EQ(out[2]["recipe"], 4);

  // Only the distortion changed: the templates (ideal pinhole, same K) stay valid.
  camera.camera.K(0, 0) /= 1.01;
  mfcd::vision::save_camera_config(camera, changed);
  EXPECT_EQ(invalidated_recipes(changed, recipes).size(), 1u);
  fs::remove_all(dir);
}
