// vision/camera load_camera_config() on a camera YAML (OpenCV FileStorage). A file that loads is
// written back with save_camera_config() and must read back to the same configuration.

#include "fuzz/fuzz_support.hpp"
#include "vision/camera/camera.hpp"

#include <stdexcept>

namespace {

using mfcd::vision::CameraConfig;

bool same(const CameraConfig& a, const CameraConfig& b) {
  if (a.camera.image_size != b.camera.image_size || a.camera.K != b.camera.K ||
      a.camera.distortion != b.camera.distortion || a.flashes.positions_mm != b.flashes.positions_mm ||
      a.flashes.ring.has_value() != b.flashes.ring.has_value() || a.working_distance_mm != b.working_distance_mm ||
      a.hand_eye.has_value() != b.hand_eye.has_value())
    return false;
  if (!a.hand_eye) return true;
  return a.hand_eye->mode == b.hand_eye->mode && a.hand_eye->camera_pose == b.hand_eye->camera_pose &&
         a.hand_eye->views == b.hand_eye->views;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto input = mfcd::fuzz::scratch_dir() / "camera.yaml";
  const auto again = mfcd::fuzz::scratch_dir() / "camera-again.yaml";
  mfcd::fuzz::write_file(input, data, size);
  CameraConfig loaded;
  try {
    loaded = mfcd::vision::load_camera_config(input);
  } catch (const std::runtime_error&) {
    return 0;  // documented: the file and the key named
  }
  mfcd::vision::save_camera_config(loaded, again);
  if (!same(loaded, mfcd::vision::load_camera_config(again))) mfcd::fuzz::finding("save/load round trip differs");
  return 0;
}
