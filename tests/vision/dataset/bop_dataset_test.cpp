// BOP writer and reader without rendering: a tiny hand-made dataset written, read back
// unchanged, and every kind of damage refused with the file and the reason.
#include "vision/dataset/bop_dataset.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <nlohmann/json.hpp>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <fstream>
#include <iterator>
#include <random>

using namespace mfcd::vision;
namespace fs = std::filesystem;

namespace {

cv::Matx33d rotation(const cv::Vec3d& w) {  // Rodrigues' formula
  const double th = cv::norm(w);
  const cv::Vec3d k = w / th;
  const cv::Matx33d Kx(0, -k[2], k[1], k[2], 0, -k[0], -k[1], k[0], 0);
  return cv::Matx33d::eye() + std::sin(th) * Kx + (1 - std::cos(th)) * Kx * Kx;
}

CameraConfig tiny_camera() {
  CameraConfig c;
  c.camera.image_size = {32, 24};
  c.camera.K = cv::Matx33d(55, 0, 15.5, 0, 56, 11.5, 0, 0, 1);
  c.flashes = FlashRing::regular({.radius_mm = 40, .first_angle_deg = 10, .step_deg = 45, .plane_z_mm = 0, .count = 8});
  c.working_distance_mm = 300;
  return c;
}

std::vector<PartModel> tiny_models() {
  PartModel a, b;
  a.obj_id = 3;
  a.name = "box";
  a.mesh = make_box(40, 20, 10);
  b.obj_id = 7;
  b.name = "cyl";
  b.mesh = make_cylinder(8, 30, 12);
  b.symmetries_continuous.push_back({{0, 0, 1}, {0, 0, 0}});
  cv::Matx44d flip = cv::Matx44d::eye();
  flip(0, 0) = flip(1, 1) = -1;
  a.symmetries_discrete.push_back(flip);
  return {a, b};
}

SimulatedImage random_image(std::mt19937& rng, const CameraConfig& cam, int instances) {
  SimulatedImage im;
  const cv::Size size = cam.camera.image_size;
  for (int k = 0; k < 8; ++k) {
    cv::Mat1b f(size);
    cv::randu(f, 0, 256);
    im.frames.flash.push_back(f);
  }
  im.frames.ambient.create(size);
  cv::randu(im.frames.ambient, 0, 40);
  im.depth_mm.create(size);
  cv::randu(im.depth_mm, 250.0, 340.0);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int g = 0; g < instances; ++g) {
    PartInstance p;
    p.obj_id = g % 2 ? 7 : 3;
    const cv::Vec3d w(u(rng), u(rng), u(rng));
    p.R = rotation(w);
    p.t_mm = {10 * u(rng), 10 * u(rng), 300 + 5 * u(rng)};
    p.mask_all = cv::Mat1b(size, 0);
    cv::rectangle(p.mask_all, cv::Rect(2 + g, 3, 10, 8), 255, cv::FILLED);
    p.mask_visib = p.mask_all.clone();
    p.mask_visib(cv::Rect(2 + g, 3, 4, 8)).setTo(0);
    p.bbox_obj = cv::boundingRect(p.mask_all);
    p.bbox_visib = cv::boundingRect(p.mask_visib);
    p.px_count_all = p.px_count_valid = cv::countNonZero(p.mask_all);
    p.px_count_visib = cv::countNonZero(p.mask_visib);
    p.visib_fract = static_cast<double>(p.px_count_visib) / p.px_count_all;
    im.instances.push_back(p);
  }
  im.corruption.removed_fraction = 0.125;
  return im;
}

class BopTiny : public testing::Test {
 protected:
  void SetUp() override {
    root = fs::temp_directory_path() /
           ("mfcd_bop_" + std::string(testing::UnitTest::GetInstance()->current_test_info()->name()) + "_" +
            std::to_string(::getpid()));
    fs::remove_all(root);
    std::mt19937 rng(11);
    BopWriter w(root);
    w.write_models(tiny_models());
    w.write_camera(cam);
    for (int s = 1; s <= 2; ++s) {
      std::vector<SimulatedImage> ims;
      for (int i = 0; i < 2; ++i) ims.push_back(random_image(rng, cam, 2 + i));
      w.write_scene(s, cam, ims);
      written.push_back(ims);
    }
  }
  void TearDown() override { fs::remove_all(root); }

  fs::path scene() const { return root / "test" / "000001"; }
  // Expects the reader (call) to fail with a message naming `file` and matching `reason`.
  template <class F>
  void expect_refused(F call, const fs::path& file, const std::string& reason) {
    try {
      call();
      ADD_FAILURE() << "accepted a dataset with " << reason;
    } catch (const std::runtime_error& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find(file.string()), std::string::npos) << msg;
      // `reason` lists the pieces the message must contain, in order, separated by "...".
      size_t at = 0;
      for (size_t from = 0; from <= reason.size();) {
        const size_t gap = std::min(reason.find("...", from), reason.size());
        const std::string piece = reason.substr(from, gap - from);
        at = msg.find(piece, at);
        ASSERT_NE(at, std::string::npos) << msg << "\n  wanted: " << reason;
        from = gap + 3;
      }
    }
  }
  void edit_json(const fs::path& file, const std::function<void(nlohmann::json&)>& edit) {
    nlohmann::json j = nlohmann::json::parse(std::ifstream(file));
    edit(j);
    std::ofstream(file) << j.dump();
  }

  CameraConfig cam = tiny_camera();
  fs::path root;
  std::vector<std::vector<SimulatedImage>> written;
};

}  // namespace

TEST_F(BopTiny, ReadsBackWhatWasWritten) {
  const BopDataset ds(root);
  EXPECT_EQ(ds.scenes(), (std::vector<int>{1, 2}));
  for (int s = 1; s <= 2; ++s) {
    EXPECT_EQ(ds.images(s), (std::vector<int>{0, 1}));
    for (int i = 0; i < 2; ++i) {
      const SimulatedImage& want = written[static_cast<size_t>(s - 1)][static_cast<size_t>(i)];
      const BopSceneCamera c = ds.camera(s, i);
      EXPECT_EQ(c.K, cam.camera.K);
      EXPECT_EQ(c.image_size, cam.camera.image_size);
      ASSERT_EQ(c.flash_positions_mm.size(), 8u);
      for (size_t k = 0; k < 8; ++k) EXPECT_EQ(c.flash_positions_mm[k], cam.flashes.positions_mm[k]);
      const CameraConfig cfg = c.config();
      EXPECT_EQ(cfg.flashes.positions_mm, cam.flashes.positions_mm);
      EXPECT_EQ(cfg.working_distance_mm, 300);
      const auto gt = ds.ground_truth(s, i);
      const auto info = ds.ground_truth_info(s, i);
      ASSERT_EQ(gt.size(), want.instances.size());
      ASSERT_EQ(info.size(), want.instances.size());
      for (size_t g = 0; g < gt.size(); ++g) {
        const PartInstance& p = want.instances[g];
        EXPECT_EQ(gt[g].obj_id, p.obj_id);
        EXPECT_EQ(gt[g].R, p.R);  // JSON doubles round-trip exactly
        EXPECT_EQ(gt[g].t_mm, p.t_mm);
        EXPECT_EQ(info[g].bbox_obj, p.bbox_obj);
        EXPECT_EQ(info[g].bbox_visib, p.bbox_visib);
        EXPECT_EQ(info[g].px_count_all, p.px_count_all);
        EXPECT_EQ(info[g].px_count_visib, p.px_count_visib);
        EXPECT_DOUBLE_EQ(info[g].visib_fract, p.visib_fract);
        EXPECT_EQ(cv::countNonZero(ds.mask_visib(s, i, static_cast<int>(g)) != p.mask_visib), 0);
      }
      const MfcFrames f = ds.frames(s, i);
      ASSERT_EQ(f.flash.size(), 8u);
      for (size_t k = 0; k < 8; ++k) EXPECT_EQ(cv::countNonZero(f.flash[k] != want.frames.flash[k]), 0);
      EXPECT_EQ(cv::countNonZero(f.ambient != want.frames.ambient), 0);
      const cv::Mat1f d = ds.depth_mm(s, i);
      EXPECT_LE(cv::norm(d, want.depth_mm, cv::NORM_INF), kBopDepthScale / 2 + 1e-4);
    }
  }
  // Models: PLY in mm, info from the mesh, symmetry hints.
  ASSERT_EQ(ds.models_info().size(), 2u);
  const BopModelInfo& box = ds.models_info().at(3);
  EXPECT_NEAR(box.diameter, std::sqrt(40 * 40 + 20 * 20 + 10 * 10), 1e-4);
  EXPECT_NEAR(box.min[0], -20, 1e-6);
  EXPECT_NEAR(box.size[1], 20, 1e-6);
  ASSERT_EQ(box.symmetries_discrete.size(), 1u);
  EXPECT_EQ(box.symmetries_discrete[0](0, 0), -1);
  ASSERT_EQ(ds.models_info().at(7).symmetries_continuous.size(), 1u);
  EXPECT_EQ(ds.models_info().at(7).symmetries_continuous[0].axis, cv::Vec3d(0, 0, 1));
  const Mesh ply = load_mesh(ds.model_path(3));
  const Mesh src = make_box(40, 20, 10);
  EXPECT_EQ(ply.triangles.size(), src.triangles.size());
  EXPECT_LT(cv::norm(ply.bbox_min() - src.bbox_min()), 1e-5);
  EXPECT_LT(cv::norm(ply.bbox_max() - src.bbox_max()), 1e-5);
}

TEST_F(BopTiny, RefusesMissingFiles) {
  fs::remove(scene() / "scene_gt.json");
  const BopDataset ds(root);
  expect_refused([&] { ds.ground_truth(1, 0); }, scene() / "scene_gt.json", "missing file");
  fs::remove(scene() / "ambient" / "000001.png");
  expect_refused([&] { ds.frames(1, 1); }, scene() / "ambient" / "000001.png", "missing image");
  fs::remove(root / "models" / "models_info.json");
  expect_refused([&] { BopDataset again(root); }, root / "models" / "models_info.json", "missing file");
  expect_refused([&] { BopDataset again(root, "train"); }, root / "train", "missing split");
}

TEST_F(BopTiny, RefusesBadJson) {
  std::ofstream(scene() / "scene_camera.json") << "{\"0\": {\"cam_K\": [1, 2,";
  const BopDataset ds(root);
  expect_refused([&] { ds.camera(1, 0); }, scene() / "scene_camera.json", "bad JSON");
}

TEST_F(BopTiny, RefusesMissingOrIllTypedKeys) {
  edit_json(scene() / "scene_camera.json", [](auto& j) { j["0"].erase("cam_K"); });
  edit_json(scene() / "scene_gt.json", [](auto& j) { j["1"][0].erase("cam_t_m2c"); });
  edit_json(scene() / "scene_gt_info.json", [](auto& j) { j["0"][1]["px_count_all"] = "many"; });
  edit_json(root / "models" / "models_info.json", [](auto& j) { j["7"].erase("diameter"); });
  expect_refused([&] { BopDataset again(root); }, root / "models" / "models_info.json", "missing key '7.diameter'");
  edit_json(root / "models" / "models_info.json", [](auto& j) { j["7"]["diameter"] = 30; });
  const BopDataset ds(root);
  expect_refused([&] { ds.camera(1, 0); }, scene() / "scene_camera.json", "missing key '0.cam_K'");
  expect_refused([&] { ds.ground_truth(1, 1); }, scene() / "scene_gt.json", "missing key '1[0].cam_t_m2c'");
  expect_refused([&] { ds.ground_truth_info(1, 0); }, scene() / "scene_gt_info.json", "0[1].px_count_all' is not");
  expect_refused([&] { ds.ground_truth(1, 5); }, scene() / "scene_gt.json", "missing key 'scene.5'");
  edit_json(scene() / "scene_camera.json", [](auto& j) { j["1"]["flash_positions_mm"][2] = {1, 2}; });
  expect_refused([&] { ds.camera(1, 1); }, scene() / "scene_camera.json", "flash_positions_mm' must be an array of 3");
}

// Numbers JSON can hold but the reader's types cannot: each is refused naming the file and the key
// (before: std::out_of_range from std::stoi, an undefined double-to-int conversion, a width
// wrapped by get<int>, nlohmann's out_of_range exception for 1e999).
TEST_F(BopTiny, RefusesNumbersOutsideTheirType) {
  edit_json(scene() / "scene_camera.json", [](auto& j) { j["99999999999"] = j["0"]; });
  {
    const BopDataset ds(root);
    expect_refused([&] { ds.images(1); }, scene() / "scene_camera.json", "key '99999999999' is not an image id");
  }
  edit_json(scene() / "scene_camera.json", [](auto& j) {
    j.erase("99999999999");
    j["0"]["width"] = 4294967936ull;  // 2^32 + 640
  });
  edit_json(scene() / "scene_gt_info.json", [](auto& j) { j["0"][0]["bbox_obj"][0] = 1e300; });
  const BopDataset ds(root);
  expect_refused([&] { ds.camera(1, 0); }, scene() / "scene_camera.json", "'0.width' = 4294967936 is out of range");
  expect_refused([&] { ds.ground_truth_info(1, 0); }, scene() / "scene_gt_info.json", "'0[0].bbox_obj' = ...out of range");
  edit_json(scene() / "scene_camera.json", [](auto& j) { j["1"]["cam_K"][0] = 12345.5; });
  {
    std::ifstream in(scene() / "scene_camera.json");
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const auto at = text.find("12345.5");
    ASSERT_NE(at, std::string::npos) << text;
    std::ofstream(scene() / "scene_camera.json") << text.replace(at, 7, "1e999");  // beyond double
  }
  expect_refused([&] { ds.camera(1, 1); }, scene() / "scene_camera.json", "bad JSON...number overflow");
}

TEST_F(BopTiny, RefusesImagesOfTheWrongSize) {
  cv::imwrite((scene() / "flash" / "000000_4.png").string(), cv::Mat1b(24, 30, uchar(9)));
  const BopDataset ds(root);
  expect_refused([&] { ds.frames(1, 0); }, scene() / "flash" / "000000_4.png", "image size 30x24 differs from 32x24");
  cv::imwrite((scene() / "depth" / "000001.png").string(), cv::Mat1w(20, 32, uint16_t(3000)));
  expect_refused([&] { ds.depth_mm(1, 1); }, scene() / "depth" / "000001.png", "image size 32x20 differs");
  // K whose principal point lies outside the image it claims to describe.
  edit_json(scene() / "scene_camera.json", [](auto& j) { j["1"]["width"] = 12; });
  expect_refused([&] { ds.frames(1, 1); }, scene() / "scene_camera.json", "principal point lies outside the 12x24");
  // A flash image in colour.
  cv::imwrite((scene() / "flash" / "000000_2.png").string(), cv::Mat3b(24, 32, cv::Vec3b(1, 2, 3)));
  expect_refused([&] { ds.frames(1, 0); }, scene() / "flash" / "000000_2.png", "single-channel 8-bit");
}

TEST_F(BopTiny, RefusesWrongNumberOfFlashImages) {
  fs::remove(scene() / "flash" / "000000_7.png");
  const BopDataset ds(root);
  expect_refused([&] { ds.frames(1, 0); }, scene() / "flash" / "000000_7.png", "missing flash image...8 flash positions");
  // One position fewer than images: the 8th image is one too many.
  edit_json(scene() / "scene_camera.json", [](auto& j) { j["1"]["flash_positions_mm"].erase(7); });
  expect_refused([&] { ds.frames(1, 1); }, scene() / "flash" / "000001_7.png", "more flash images than the 7");
}

// A dataset laid out as the BOP toolkit's docs describe it (docs/bop_datasets_format.md): the
// image size lives in camera.json only, scene_camera.json holds cam_K, depth_scale and the
// world-to-camera pose, and nothing says where the LEDs are. It reads with the flash positions of
// a camera file, and each missing piece is refused with the file, the key and where else to look.
TEST_F(BopTiny, ReadsAStandardBopLayoutWithFlashesFromACameraFile) {
  for (int s = 1; s <= 2; ++s)
    edit_json(root / "test" / (s == 1 ? "000001" : "000002") / "scene_camera.json", [](auto& j) {
      for (auto& [id, e] : j.items()) {
        for (const char* k : {"width", "height", "flash_positions_mm", "working_distance_mm"}) e.erase(k);
        e["cam_R_w2c"] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
        e["cam_t_w2c"] = {0, 0, 0};
      }
    });
  const nlohmann::json camera_json = nlohmann::json::parse(std::ifstream(root / "camera.json"));
  ASSERT_EQ(camera_json["width"], 32);
  ASSERT_EQ(camera_json["height"], 24);

  const BopDataset ds(root, "test", {cam.flashes.positions_mm, "tiny camera"});
  const BopSceneCamera c = ds.camera(1, 1);
  EXPECT_EQ(c.image_size, cv::Size(32, 24));
  EXPECT_EQ(c.K, cam.camera.K);
  ASSERT_EQ(c.flash_positions_mm.size(), 8u);
  for (size_t k = 0; k < 8; ++k) EXPECT_EQ(c.flash_positions_mm[k], cam.flashes.positions_mm[k]);
  EXPECT_EQ(c.working_distance_mm, 0);
  const MfcFrames f = ds.frames(1, 1);
  ASSERT_EQ(f.flash.size(), 8u);
  EXPECT_EQ(cv::norm(f.flash[3], written[0][1].frames.flash[3], cv::NORM_INF), 0);
  EXPECT_EQ(ds.depth_mm(2, 0).size(), cv::Size(32, 24));

  // No camera file: the flash positions are missing, and the message says what to give.
  const BopDataset bare(root);
  expect_refused([&] { bare.frames(1, 0); }, scene() / "scene_camera.json",
                 "missing key '0.flash_positions_mm'...--camera");
  // No image size anywhere.
  edit_json(root / "camera.json", [](auto& j) { j.erase("width"); j.erase("height"); });
  const BopDataset sizeless(root, "test", {cam.flashes.positions_mm, "tiny camera"});
  expect_refused([&] { sizeless.camera(1, 0); }, scene() / "scene_camera.json",
                 "missing key '0.width'...camera.json gives no width and height");
  fs::remove(root / "camera.json");
  const BopDataset no_camera_json(root, "test", {cam.flashes.positions_mm, "tiny camera"});
  expect_refused([&] { no_camera_json.camera(1, 0); }, scene() / "scene_camera.json",
                 "missing key '0.width'...camera.json does not exist");
  // The images must agree with camera.json's size.
  std::ofstream(root / "camera.json") << R"({"cx": 15.5, "cy": 11.5, "fx": 55, "fy": 56, "width": 30, "height": 24,
                                            "depth_scale": 0.1})";
  const BopDataset narrow(root, "test", {cam.flashes.positions_mm, "tiny camera"});
  expect_refused([&] { narrow.frames(1, 0); }, scene() / "flash" / "000000_0.png", "image size 32x24 differs from 30x24");
  // A malformed camera.json is refused when the dataset is opened.
  std::ofstream(root / "camera.json") << R"({"width": "wide", "height": 24})";
  expect_refused([&] { BopDataset again(root); }, root / "camera.json", "'width' is not an integer");
}
