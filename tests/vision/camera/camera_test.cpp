#include "vision/camera/camera.hpp"

#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

using namespace mfcd::vision;
namespace fs = std::filesystem;

namespace {

fs::path temp_file(const std::string& name) {
  fs::path dir = fs::temp_directory_path() / ("mfcd-camera-test-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir / name;
}

std::string read_all(const fs::path& p) {
  std::ifstream in(p);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

void write_all(const fs::path& p, const std::string& s) { std::ofstream(p) << s; }

// Runs load_camera_config and returns the error message (empty if it loaded).
std::string load_error(const fs::path& p) {
  try {
    load_camera_config(p);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

const fs::path kSimYaml = fs::path(MFC_SOURCE_DIR) / "config" / "camera-sim.yaml";

// The simulated camera's file with `from` replaced by `to` (which must occur), at `name`.
fs::path edited_sim_yaml(const std::string& from, const std::string& to, const std::string& name) {
  std::string text = read_all(kSimYaml);
  const auto at = text.find(from);
  if (at == std::string::npos) throw std::logic_error("camera-sim.yaml has no '" + from + "'");
  text.replace(at, from.size(), to);
  const fs::path p = temp_file(name);
  write_all(p, text);
  return p;
}

// Records the largest matrix OpenCV is asked to allocate while installed, and refuses (as
// OpenCV's own out-of-memory error) any above 64 MB, so a size read from a file and used
// unchecked shows up here instead of in the machine's memory.
class LargestMatAllocation : public cv::MatAllocator {
 public:
  LargestMatAllocation() : std_(cv::Mat::getStdAllocator()), previous_(cv::Mat::getDefaultAllocator()) {
    cv::Mat::setDefaultAllocator(this);
  }
  ~LargestMatAllocation() override { cv::Mat::setDefaultAllocator(previous_); }
  double largest_bytes() const { return largest_; }

  cv::UMatData* allocate(int dims, const int* sizes, int type, void* data, size_t* step, cv::AccessFlag flags,
                         cv::UMatUsageFlags usage) const override {
    double bytes = CV_ELEM_SIZE(type);
    for (int i = 0; i < dims; ++i) bytes *= sizes[i];
    largest_ = std::max(largest_, bytes);
    if (bytes > 64e6) CV_Error(cv::Error::StsNoMem, "test allocator: refused " + std::to_string(bytes) + " bytes");
    return std_->allocate(dims, sizes, type, data, step, flags, usage);
  }
  bool allocate(cv::UMatData* data, cv::AccessFlag flags, cv::UMatUsageFlags usage) const override {
    return std_->allocate(data, flags, usage);
  }
  void deallocate(cv::UMatData* data) const override { std_->deallocate(data); }

 private:
  cv::MatAllocator* std_;
  cv::MatAllocator* previous_;
  mutable double largest_ = 0;
};

// Caps the process's address space at what it maps now plus `mb` (the count tests run this in a
// death-test child). Not under AddressSanitizer or ThreadSanitizer, whose shadow memory maps
// terabytes: there an oversized allocation aborts the test by itself.
void cap_address_space(long mb) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  (void)mb;
#else
  long pages = 0;
  std::ifstream("/proc/self/statm") >> pages;
  const auto cap = static_cast<rlim_t>(pages * ::sysconf(_SC_PAGESIZE) + (mb << 20));
  const rlimit limit{cap, cap};
  ::setrlimit(RLIMIT_AS, &limit);
#endif
}

}  // namespace

TEST(CameraConfig, DefaultSimulationFileLoads) {
  const CameraConfig c = load_camera_config(kSimYaml);
  EXPECT_EQ(c.camera.image_size, cv::Size(640, 480));
  EXPECT_DOUBLE_EQ(c.camera.fx(), 1100.0);
  EXPECT_DOUBLE_EQ(c.working_distance_mm, 300.0);
  ASSERT_EQ(c.flashes.positions_mm.size(), 8u);
  ASSERT_TRUE(c.flashes.ring.has_value());
  // LED 0 on +x (image right), LED 2 on +y (image down), 40 mm from the axis.
  EXPECT_NEAR(c.flashes.positions_mm[0][0], 40.0, 1e-12);
  EXPECT_NEAR(c.flashes.positions_mm[2][1], 40.0, 1e-12);
  for (const auto& p : c.flashes.positions_mm) EXPECT_NEAR(std::hypot(p[0], p[1]), 40.0, 1e-9);
  // A 40-80 mm part at the working distance spans about 150-290 px, as the file promises.
  EXPECT_NEAR(c.camera.fx() * 40 / c.working_distance_mm, 146.7, 0.1);
}

TEST(CameraConfig, RoundTripsRingAndMeasuredPositions) {
  CameraConfig c = load_camera_config(kSimYaml);
  c.camera.K(0, 2) = 321.25;
  c.camera.distortion = {0.1, -0.02, 0.001, 0.002, 0.003};
  const fs::path ring = temp_file("ring.yaml");
  save_camera_config(c, ring);
  const CameraConfig r = load_camera_config(ring);
  EXPECT_EQ(r.camera.K, c.camera.K);
  EXPECT_EQ(r.camera.distortion, c.camera.distortion);
  EXPECT_EQ(r.flashes.positions_mm, c.flashes.positions_mm);

  c.flashes.ring.reset();
  c.flashes.positions_mm[3] += cv::Vec3d(0.5, -0.25, 1.0);  // a measured, off-ring LED
  const fs::path measured = temp_file("measured.yaml");
  save_camera_config(c, measured);
  const CameraConfig m = load_camera_config(measured);
  EXPECT_FALSE(m.flashes.ring.has_value());
  EXPECT_EQ(m.flashes.positions_mm, c.flashes.positions_mm);
}

TEST(CameraConfig, MissingKeyIsNamedWithTheFile) {
  std::string text = read_all(kSimYaml);
  const auto at = text.find("working_distance_mm");
  text.replace(at, std::string("working_distance_mm").size(), "working_distance_cm");
  const fs::path p = temp_file("missing.yaml");
  write_all(p, text);
  const std::string err = load_error(p);
  EXPECT_NE(err.find("working_distance_mm"), std::string::npos) << err;
  EXPECT_NE(err.find(p.string()), std::string::npos) << err;
}

TEST(CameraConfig, MalformedValuesAreNamed) {
  struct Case {
    std::string from, to, key;
  };
  const std::vector<Case> cases = {
      {"image_width: 640", "image_width: wide", "image_width"},
      {"image_height: 480", "image_height: -4", "image_height"},
      {"ring_radius_mm: 40.", "ring_radius_mm: [1, 2]", "flashes.ring_radius_mm"},
      {"count: 8", "count: 6", "flashes.count"},
      {"data: [ 1100., 0., 319.5", "data: [ -1100., 0., 319.5", "camera_matrix"},
      {"cols: 5", "cols: 1", "distortion_coefficients"},
  };
  for (const auto& c : cases) {
    std::string text = read_all(kSimYaml);
    const auto at = text.find(c.from);
    ASSERT_NE(at, std::string::npos) << c.from;
    text.replace(at, c.from.size(), c.to);
    const fs::path p = temp_file("bad.yaml");
    write_all(p, text);
    const std::string err = load_error(p);
    EXPECT_NE(err.find("'" + c.key + "'"), std::string::npos) << c.to << " -> " << err;
    EXPECT_NE(err.find(p.string()), std::string::npos) << err;
  }
}

// Every matrix's rows, cols and data length are checked before OpenCV sizes a matrix by them
// (cv::read allocates rows x cols before it compares them with the data).
TEST(CameraConfig, MatrixSizesAreCheckedBeforeAllocating) {
  struct Case {
    std::string from, to, key;
  };
  const std::vector<Case> cases = {
      {"rows: 3\n   cols: 3", "rows: 2000000000\n   cols: 3", "camera_matrix"},
      {"rows: 3\n   cols: 3", "rows: -3\n   cols: 3", "camera_matrix"},
      {"rows: 1\n   cols: 5", "rows: 1\n   cols: 2000000000", "distortion_coefficients"},
      {"rows: 1\n   cols: 5", "rows: 1\n   cols: 3", "distortion_coefficients"},
      {"data: [ 0., 0., 0., 0., 0. ]", "data: [ 0., 0., 0. ]", "distortion_coefficients"},
      {"dt: d\n   data: [ 1100.", "dt: \"3d\"\n   data: [ 1100.", "camera_matrix"},
      {"   ring_radius_mm: 40.",
       "   positions_mm: !!opencv-matrix\n      rows: 2000000000\n      cols: 3\n      dt: d\n      data: [ 1., 2., 3. "
       "]\n"
       "   ring_radius_mm: 40.",
       "flashes.positions_mm"},
      {"working_distance_mm: 300.",
       "working_distance_mm: 300.\nhand_eye:\n   mode: eye_to_hand\n   camera_pose: !!opencv-matrix\n      rows: "
       "100000\n"
       "      cols: 100000\n      dt: d\n      data: [ 1. ]\n   reprojection_rms_px: 0.\n   residual_rms_mm: 0.\n"
       "   views: 1",
       "hand_eye.camera_pose"},
  };
  for (const auto& c : cases) {
    const fs::path p = edited_sim_yaml(c.from, c.to, "matrix-size.yaml");
    LargestMatAllocation allocator;
    const std::string err = load_error(p);
    EXPECT_NE(err.find("'" + c.key + "'"), std::string::npos) << c.to << " -> " << err;
    EXPECT_NE(err.find(p.string()), std::string::npos) << err;
    EXPECT_LT(allocator.largest_bytes(), 1e6) << c.to;
  }
}

// flashes.count is checked before the ring's positions are generated from it.
TEST(CameraConfig, FlashCountIsCheckedBeforeTheRingIsBuilt) {
  for (const char* count : {"count: 2000000000", "count: -8", "count: 0"}) {
    const fs::path p = edited_sim_yaml("count: 8", count, "count.yaml");
    EXPECT_EXIT(
        {
          cap_address_space(256);
          const std::string err = load_error(p);
          std::fprintf(stderr, "%s\n", err.c_str());
          std::exit(err.find("'flashes.count'") != std::string::npos && err.find(p.string()) != std::string::npos ? 0
                                                                                                                  : 1);
        },
        ::testing::ExitedWithCode(0), "")
        << count;
  }
}

// Measured positions list exactly 8 rows, and a ring count beside them must agree.
TEST(CameraConfig, MeasuredPositionsAgreeWithTheLedCount) {
  CameraConfig c = load_camera_config(kSimYaml);
  c.flashes.ring.reset();
  const fs::path measured = temp_file("measured-count.yaml");
  save_camera_config(c, measured);
  const std::string text = read_all(measured);
  const auto at = text.find("positions_mm");
  ASSERT_NE(at, std::string::npos);
  std::string with_count = text;
  with_count.insert(at, "count: 6\n   ");
  write_all(measured, with_count);
  EXPECT_NE(load_error(measured).find("'flashes.count'"), std::string::npos) << load_error(measured);
  with_count = text;
  with_count.insert(at, "count: 8\n   ");
  write_all(measured, with_count);
  EXPECT_EQ(load_error(measured), "");
}

TEST(CameraConfig, NotYamlOrMissingFileIsAnError) {
  const fs::path p = temp_file("garbage.yaml");
  write_all(p, "%YAML:1.0\n---\nimage_width: [unclosed\n");
  EXPECT_NE(load_error(p).find(p.string()), std::string::npos);
  EXPECT_NE(load_error(temp_file("does-not-exist.yaml")).find("does-not-exist.yaml"), std::string::npos);
}

// Inputs the fuzzer found (fuzz/corpus/camera_config/crash-*, timeout-*): each crashed, hung or
// threw another exception than std::runtime_error while OpenCV's FileStorage read the files.
TEST(CameraConfig, MalformedFilesFoundByFuzzingAreRefused) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"xml.yaml", std::string("<?xml n=\0", 9)},                 // OpenCV 4.6's XML parser: NULL dereference
      {"sequence.yaml", "%YAML:1.0\n---\n- 640\n- 480\n"},        // cv::Exception: FileNode::operator[] on a non-map
      {"empty-key.yaml", "%YAML:1.0\n---\na:\n   b: 3\n   :\n"},  // std::length_error from OpenCV's YAML parser
      {"loop.yaml", "%YAML:1.\n t:d\no 0-\n"},                    // OpenCV 4.6's YAML parser never returns
  };
  for (const auto& [name, text] : cases) {
    const fs::path p = temp_file(name);
    std::ofstream(p, std::ios::binary) << text;
    std::string err;
    try {
      load_camera_config(p);
    } catch (const std::runtime_error& e) {
      err = e.what();
    }
    EXPECT_NE(err.find(p.string()), std::string::npos) << name << ": " << err;
  }
}

// save_camera_config writes YAML for any extension, so the file reads back.
TEST(CameraConfig, SavedFileIsYamlWhateverItsName) {
  const CameraConfig c = load_camera_config(kSimYaml);
  const fs::path xml = temp_file("camera.xml");
  save_camera_config(c, xml);
  EXPECT_EQ(read_all(xml).rfind("%YAML:1.0", 0), 0u);
  EXPECT_EQ(load_camera_config(xml).camera.K, c.camera.K);
}

// The closed-form shadow direction against the definition: the image of P + s (P - L)
// for a small s > 0 (P moved away from the LED along the light ray).
TEST(FlashEpipole, ShadowDirectionMatchesProjectedLightRay) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  PinholeCamera cam;
  cam.K = cv::Matx33d(1100, 0, 319.5, 0, 1050, 239.5, 0, 0, 1);
  for (int trial = 0; trial < 1000; ++trial) {
    const cv::Vec3d L(60 * u(rng), 60 * u(rng), trial % 2 ? 0.0 : 20 * u(rng));
    const cv::Vec3d P(100 * u(rng), 80 * u(rng), 300 + 100 * u(rng));
    const cv::Point2d p = cam.project(P);
    const cv::Point2d q = cam.project(P + 1e-4 * (P - L));
    const cv::Vec2d expect = cv::normalize(cv::Vec2d(q.x - p.x, q.y - p.y));
    const cv::Vec2d got = cv::normalize(flash_epipole(cam, L).shadow_direction(p.x, p.y));
    EXPECT_NEAR(expect.dot(got), 1.0, 1e-6) << "trial " << trial;
  }
}

TEST(PinholeCamera, CroppedCameraProjectsIntoTheWindow) {
  PinholeCamera cam;
  cam.K = cv::Matx33d(1100, 0, 319.5, 0, 1100, 239.5, 0, 0, 1);
  const cv::Rect win(100, 50, 200, 150);
  const PinholeCamera c = cam.cropped(win);
  EXPECT_EQ(c.image_size, win.size());
  const cv::Vec3d P(12, -7, 310);
  EXPECT_NEAR(c.project(P).x, cam.project(P).x - win.x, 1e-9);
  EXPECT_NEAR(c.project(P).y, cam.project(P).y - win.y, 1e-9);
}

// OpenCV's calibration tutorial marks cv::fisheye coefficients with fisheye_model: 1; read as
// pinhole k1 k2 p1 p2 they would undistort every frame wrongly, so the file is refused by name.
TEST(CameraConfig, FisheyeFileIsRefusedWithTheReason) {
  const fs::path fisheye =
      edited_sim_yaml("working_distance_mm", "fisheye_model: 1\nworking_distance_mm", "fisheye.yaml");
  const std::string err = load_error(fisheye);
  EXPECT_NE(err.find("fisheye_model"), std::string::npos) << err;
  EXPECT_NE(err.find(fisheye.string()), std::string::npos) << err;
  EXPECT_NE(err.find("fisheye lenses are not supported: mfcd's camera model is the pinhole with polynomial distortion"),
            std::string::npos)
      << err;
  const fs::path pinhole =
      edited_sim_yaml("working_distance_mm", "fisheye_model: 0\nworking_distance_mm", "pinhole.yaml");
  EXPECT_EQ(load_error(pinhole), "") << "fisheye_model: 0 is the pinhole model";
  const fs::path junk = edited_sim_yaml("working_distance_mm", "fisheye_model: yes\nworking_distance_mm", "junk.yaml");
  EXPECT_NE(load_error(junk).find("fisheye_model"), std::string::npos);
}
