// daemon/config.hpp parse_config() on the daemon's YAML configuration (docs/configuration.md),
// with a search path holding the files the seeds name (a camera YAML with and without a
// hand_eye section, the six parts' templates and meshes as empty files). ConfigError is the
// documented refusal; any other exception is a finding.

#include "daemon/config.hpp"
#include "fuzz/fuzz_support.hpp"

#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

constexpr const char* kCamera = R"(%YAML:1.0
---
image_width: 640
image_height: 480
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 1100., 0., 319.5, 0., 1100., 239.5, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [ 0., 0., 0., 0., 0. ]
working_distance_mm: 300.
flashes:
   ring_radius_mm: 40.
   first_angle_deg: 0.
   step_deg: 45.
   plane_z_mm: 0.
   count: 8
)";

constexpr const char* kHandEye = R"(hand_eye:
   mode: eye_to_hand
   camera_pose: !!opencv-matrix
      rows: 4
      cols: 4
      dt: d
      data: [ 1., 0., 0., 500., 0., -1., 0., 0., 0., 0., -1., 800., 0., 0., 0., 1. ]
   reprojection_rms_px: 0.2
   residual_rms_mm: 0.5
   views: 12
)";

const std::vector<fs::path>& search_path() {
  static const std::vector<fs::path> path = [] {
    const fs::path d = mfcd::fuzz::scratch_dir() / "data";
    fs::create_directories(d / "templates");
    fs::create_directories(d / "parts");
    mfcd::fuzz::write_file(d / "camera-sim.yaml", kCamera);
    mfcd::fuzz::write_file(d / "camera-he.yaml", std::string(kCamera) + kHandEye);
    for (const char* part : {"breaker", "diamond", "ellipse", "tnut", "knob", "wheel"}) {
      mfcd::fuzz::write_file(d / "templates" / (std::string(part) + ".tdb"), "");
      mfcd::fuzz::write_file(d / "parts" / (std::string(part) + ".stl"), "");
    }
    return std::vector<fs::path>{d};
  }();
  return path;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    mfcd::daemon::parse_config(text, "fuzz.yaml", search_path());
  } catch (const mfcd::daemon::ConfigError&) {
    // documented: the source, line and key named
  }
  return 0;
}
