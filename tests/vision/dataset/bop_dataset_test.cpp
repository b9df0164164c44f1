// BOP writer and reader without rendering: a tiny hand-made dataset written, read back
// unchanged, and every kind of damage refused with the file and the reason; the files the BOP
// toolkit looks for beside them (PLY normals, models_eval/, test_targets_bop19.json, gray/).
#include "vision/dataset/bop_dataset.hpp"
#include "vision/model/ply_reader.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <unistd.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <random>
#include <sstream>

using namespace mfcd::vision;
namespace fs = std::filesystem;

namespace mfcd::vision {
// For gtest's messages.
void PrintTo(const BopTestTarget& t, std::ostream* os) {
  *os << "{scene " << t.scene_id << ", im " << t.im_id << ", obj " << t.obj_id << ", count " << t.inst_count << "}";
}
}  // namespace mfcd::vision

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
    targets = w.write_test_targets();
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
  std::vector<BopTestTarget> targets;  // what write_test_targets returned
};

std::string file_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// An ASCII PLY's vertex rows read the way the BOP toolkit's inout.load_ply reads them: the vertex
// element's property names from the header, then one line of numbers per vertex.
struct PlyVertexRows {
  std::vector<std::string> names, types;  // of the vertex element's properties
  std::vector<std::vector<double>> rows;
  int column(const std::string& name) const {
    const auto it = std::find(names.begin(), names.end(), name);
    return it == names.end() ? -1 : static_cast<int>(it - names.begin());
  }
};

PlyVertexRows read_ply_vertex_rows(const fs::path& file) {
  std::ifstream in(file);
  PlyVertexRows out;
  std::string line;
  size_t count = 0;
  bool in_vertex = false, ended = false;
  while (std::getline(in, line)) {
    std::istringstream w(line);
    std::string key;
    w >> key;
    if (key == "end_header") {
      ended = true;
      break;
    }
    if (key == "element") {
      std::string name;
      w >> name;
      in_vertex = name == "vertex";
      if (in_vertex) w >> count;
    } else if (key == "property" && in_vertex) {
      std::string type, name;
      w >> type >> name;
      out.types.push_back(type);
      out.names.push_back(name);
    }
  }
  EXPECT_TRUE(ended) << file << ": no end_header";
  for (size_t i = 0; i < count && std::getline(in, line); ++i) {
    std::istringstream w(line);
    std::vector<double> row;
    for (double v; w >> v;) row.push_back(v);
    EXPECT_EQ(row.size(), out.names.size()) << file << " vertex " << i << ": " << line;
    out.rows.push_back(row);
  }
  EXPECT_EQ(out.rows.size(), count) << file;
  return out;
}

// BOP19 targets counted straight from the JSON files, as scripts/enumerate_test_targets.py
// counts them (visib_fract >= 0.1; per image, object ids in the order of first appearance).
std::vector<BopTestTarget> targets_from_files(const fs::path& split_dir) {
  std::vector<BopTestTarget> out;
  std::vector<fs::path> scenes;
  for (const auto& e : fs::directory_iterator(split_dir)) scenes.push_back(e.path());
  std::sort(scenes.begin(), scenes.end());
  for (const auto& dir : scenes) {
    const auto gt = nlohmann::json::parse(std::ifstream(dir / "scene_gt.json"));
    const auto info = nlohmann::json::parse(std::ifstream(dir / "scene_gt_info.json"));
    std::vector<int> ims;
    for (const auto& [key, v] : gt.items()) ims.push_back(std::stoi(key));
    std::sort(ims.begin(), ims.end());
    for (int im : ims) {
      std::vector<std::pair<int, int>> counts;  // obj_id, visible instances
      const auto& list = gt[std::to_string(im)];
      for (size_t g = 0; g < list.size(); ++g) {
        if (info[std::to_string(im)][g]["visib_fract"].get<double>() < 0.1) continue;
        const int obj = list[g]["obj_id"].get<int>();
        auto it = std::find_if(counts.begin(), counts.end(), [&](const auto& c) { return c.first == obj; });
        if (it == counts.end())
          counts.push_back({obj, 1});
        else
          ++it->second;
      }
      for (const auto& [obj, n] : counts) out.push_back({std::stoi(dir.filename().string()), im, obj, n});
    }
  }
  return out;
}

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

// Several views of one scene: BOP's cam_R_w2c / cam_t_w2c give each camera in the scene's world.
TEST_F(BopTiny, ReadsEachViewsWorldPoseAndRefusesANonRotation) {
  const double c = std::cos(0.4), s = std::sin(0.4);
  edit_json(scene() / "scene_camera.json", [&](auto& j) {
    j["1"]["cam_R_w2c"] = {1, 0, 0, 0, c, -s, 0, s, c};
    j["1"]["cam_t_w2c"] = {0, 12.5, -3};
  });
  {
    const BopDataset ds(root);
    EXPECT_FALSE(ds.camera(1, 0).has_world_pose);
    const BopSceneCamera cam = ds.camera(1, 1);
    ASSERT_TRUE(cam.has_world_pose);
    EXPECT_DOUBLE_EQ(cam.R_w2c(1, 2), -s);
    EXPECT_DOUBLE_EQ(cam.R_w2c(2, 1), s);
    EXPECT_DOUBLE_EQ(cam.t_w2c_mm[1], 12.5);
  }
  edit_json(scene() / "scene_camera.json", [](auto& j) { j["1"]["cam_R_w2c"] = {1, 0, 0, 0, 2, 0, 0, 0, 1}; });
  {
    const BopDataset ds(root);
    expect_refused([&] { ds.camera(1, 1); }, scene() / "scene_camera.json", "'1.cam_R_w2c' is not a rotation");
  }
  edit_json(scene() / "scene_camera.json", [](auto& j) { j["1"].erase("cam_t_w2c"); });
  const BopDataset ds(root);
  expect_refused([&] { ds.camera(1, 1); }, scene() / "scene_camera.json", "missing key '1.cam_t_w2c'");
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
  expect_refused([&] { ds.ground_truth_info(1, 0); }, scene() / "scene_gt_info.json",
                 "'0[0].bbox_obj' = ...out of range");
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
  expect_refused([&] { ds.frames(1, 0); }, scene() / "flash" / "000000_7.png",
                 "missing flash image...8 flash positions");
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
  edit_json(root / "camera.json", [](auto& j) {
    j.erase("width");
    j.erase("height");
  });
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
  expect_refused([&] { narrow.frames(1, 0); }, scene() / "flash" / "000000_0.png",
                 "image size 32x24 differs from 30x24");
  // A malformed camera.json is refused when the dataset is opened.
  std::ofstream(root / "camera.json") << R"({"width": "wide", "height": 24})";
  expect_refused([&] { BopDataset again(root); }, root / "camera.json", "'width' is not an integer");
}

// Every vertex of the written PLY models carries a float normal nx ny nz of unit length that
// points out of the (closed, convex) mesh, and the project's own PLY reader still reads the files
// as the meshes that were written.
TEST_F(BopTiny, PlyModelsCarryUnitOutwardNormals) {
  const std::vector<PartModel> models = tiny_models();
  for (const PartModel& m : models) {
    const fs::path file = root / "models" / ("obj_00000" + std::to_string(m.obj_id) + ".ply");
    const PlyVertexRows ply = read_ply_vertex_rows(file);
    ASSERT_EQ(ply.names, (std::vector<std::string>{"x", "y", "z", "nx", "ny", "nz"})) << file;
    EXPECT_EQ(ply.types, (std::vector<std::string>(6, "float"))) << file;
    ASSERT_EQ(ply.rows.size(), m.mesh.vertices.size());
    cv::Vec3d centroid(0, 0, 0);
    for (const auto& r : ply.rows) centroid += cv::Vec3d(r[0], r[1], r[2]) / static_cast<double>(ply.rows.size());
    for (size_t i = 0; i < ply.rows.size(); ++i) {
      const auto& r = ply.rows[i];
      const cv::Vec3d v(r[0], r[1], r[2]), n(r[3], r[4], r[5]);
      EXPECT_NEAR(cv::norm(n), 1.0, 1e-6) << file << " vertex " << i;
      EXPECT_GT(n.dot(v - centroid), 0.1 * cv::norm(v - centroid)) << file << " vertex " << i << " normal " << n;
    }
    // The project's reader skips the normals: the same vertices (exactly: 9 digits hold a float)
    // and triangles.
    const Mesh back = read_ply(file);
    EXPECT_EQ(back.vertices, m.mesh.vertices) << file;
    EXPECT_EQ(back.triangles, m.mesh.triangles) << file;
    EXPECT_EQ(load_mesh(file).vertices.size(), m.mesh.vertices.size()) << file;
  }
}

// Normals by vertex index: triangles with vertices of their own get their face's normal exactly;
// the shared corners of a box the area-weighted mean, on the corner's diagonal side; a vertex no
// triangle uses gets none; an index outside the vertices is refused.
TEST(VertexNormals, SplitTrianglesKeepTheirFaceNormalsAndSharedVerticesAverage) {
  const Mesh box = make_box(40, 20, 10);
  Mesh split;
  for (const auto& t : box.triangles) {
    const auto base = static_cast<uint32_t>(split.vertices.size());
    for (uint32_t i : t) split.vertices.push_back(box.vertices[i]);
    split.triangles.push_back({base, base + 1, base + 2});
  }
  const std::vector<cv::Vec3f> flat = vertex_normals(split);
  ASSERT_EQ(flat.size(), split.vertices.size());
  for (size_t f = 0; f < split.triangles.size(); ++f) {
    const auto& t = split.triangles[f];
    const cv::Vec3f a = split.vertices[t[0]], b = split.vertices[t[1]], c = split.vertices[t[2]];
    const cv::Vec3f centre = (a + b + c) / 3.f;
    // The box's face normal: the axis along which the triangle's centre lies on the face plane.
    cv::Vec3f want(0, 0, 0);
    const cv::Vec3f half(20, 10, 5);
    for (int k = 0; k < 3; ++k)
      if (std::abs(std::abs(centre[k]) - half[k]) < 1e-4f) want[k] = centre[k] > 0 ? 1.f : -1.f;
    ASSERT_EQ(cv::norm(want), 1.0) << "triangle " << f;
    for (uint32_t i : t) EXPECT_LT(cv::norm(flat[i] - want), 1e-6) << "triangle " << f << " normal " << flat[i];
  }
  Mesh shared = box;
  shared.vertices.emplace_back(0.f, 0.f, 0.f);  // used by no triangle
  const std::vector<cv::Vec3f> smooth = vertex_normals(shared);
  for (size_t i = 0; i < box.vertices.size(); ++i)
    for (int k = 0; k < 3; ++k)
      EXPECT_GT(smooth[i][k] * box.vertices[i][k], 0) << "corner " << i << " normal " << smooth[i];
  EXPECT_EQ(smooth.back(), cv::Vec3f(0, 0, 0));
  Mesh bad = box;
  bad.triangles.push_back({0, 1, 8});
  EXPECT_THROW(vertex_normals(bad), std::invalid_argument);
}

// models_eval/ holds the very models and models_info.json of models/, where the BOP toolkit's
// evaluation (dataset_params.get_model_params with model_type "eval") looks for them.
TEST_F(BopTiny, ModelsEvalHoldsTheSameModelsAndInfo) {
  for (const char* name : {"obj_000003.ply", "obj_000007.ply", "models_info.json"}) {
    ASSERT_TRUE(fs::exists(root / "models_eval" / name)) << name;
    EXPECT_EQ(file_bytes(root / "models_eval" / name), file_bytes(root / "models" / name)) << name;
  }
  const auto info = nlohmann::json::parse(std::ifstream(root / "models_eval" / "models_info.json"));
  ASSERT_TRUE(info.contains("3") && info.contains("7")) << info.dump();
  EXPECT_NEAR(info["3"]["diameter"].get<double>(), std::sqrt(40 * 40 + 20 * 20 + 10 * 10), 1e-4);
  // Ids must be usable as BOP's: distinct and not negative.
  std::vector<PartModel> twice = tiny_models();
  twice[1].obj_id = twice[0].obj_id;
  BopWriter w(root);
  EXPECT_THROW(w.write_models(twice), std::invalid_argument);
  twice[1].obj_id = -2;
  EXPECT_THROW(w.write_models(twice), std::invalid_argument);
}

// test_targets_bop19.json at the root: one entry per (scene, image, object id) with inst_count
// the instances at least 10 % visible, exactly as counted from the written scene files.
TEST_F(BopTiny, TestTargetsMatchTheSceneGroundTruth) {
  // A third scene whose visibilities sit on both sides of the threshold: obj 7 first (0.5 and
  // 0.1 count), obj 3 (0.05 does not, 0.75 does); in image 1 obj 7 has only 0.09, so no entry.
  std::mt19937 rng(5);
  std::vector<SimulatedImage> ims = {random_image(rng, cam, 4), random_image(rng, cam, 2)};
  const int objs0[] = {7, 3, 7, 3};
  const double vis0[] = {0.5, 0.05, 0.1, 0.75};
  for (size_t g = 0; g < 4; ++g) ims[0].instances[g].obj_id = objs0[g], ims[0].instances[g].visib_fract = vis0[g];
  ims[1].instances[0].obj_id = 7, ims[1].instances[0].visib_fract = 0.09;
  ims[1].instances[1].obj_id = 3, ims[1].instances[1].visib_fract = 0.3;
  BopWriter w(root);
  w.write_scene(3, cam, ims);
  const std::vector<BopTestTarget> got = w.write_test_targets();

  const fs::path file = root / "test_targets_bop19.json";
  ASSERT_TRUE(fs::exists(file));
  const auto j = nlohmann::json::parse(std::ifstream(file));
  ASSERT_TRUE(j.is_array());
  std::vector<BopTestTarget> in_file;
  for (const auto& e : j) {
    ASSERT_EQ(e.size(), 4u) << e.dump();  // exactly BOP's keys
    in_file.push_back({e.at("scene_id").get<int>(), e.at("im_id").get<int>(), e.at("obj_id").get<int>(),
                       e.at("inst_count").get<int>()});
  }
  EXPECT_EQ(in_file, got);
  EXPECT_EQ(in_file, targets_from_files(root / "test"));
  // The hand-made scene, by hand.
  std::vector<BopTestTarget> scene3;
  for (const auto& t : in_file)
    if (t.scene_id == 3) scene3.push_back(t);
  EXPECT_EQ(scene3, (std::vector<BopTestTarget>{{3, 0, 7, 2}, {3, 0, 3, 1}, {3, 1, 3, 1}}));
  // The fixture's scenes: every instance is 60 % visible, so every one counts.
  int counted = 0;
  for (const auto& t : in_file)
    if (t.scene_id < 3) counted += t.inst_count;
  EXPECT_EQ(counted, 2 * (2 + 3));
  // What the fixture's write_test_targets returned before scene 3 was there.
  std::vector<BopTestTarget> first_two;
  for (const auto& t : in_file)
    if (t.scene_id < 3) first_two.push_back(t);
  EXPECT_EQ(targets, first_two);
}

TEST_F(BopTiny, TestTargetsRefuseDisagreeingSceneFilesAndBadSplits) {
  EXPECT_EQ(bop_test_targets_filename("test"), "test_targets_bop19.json");
  EXPECT_EQ(bop_test_targets_filename("val"), "val_targets_bop19.json");
  EXPECT_EQ(bop_test_targets_filename("test_primesense"), "test_targets_bop19.json");
  edit_json(scene() / "scene_gt_info.json", [](auto& j) { j["1"].erase(0); });
  expect_refused([&] { bop_test_targets(root, "test"); }, scene() / "scene_gt_info.json",
                 "'1' lists 2 instances...scene_gt.json lists 3");
  edit_json(scene() / "scene_gt_info.json", [](auto& j) { j.erase("1"); });
  expect_refused([&] { bop_test_targets(root, "test"); }, scene() / "scene_gt_info.json", "missing key 'scene.1'");
  expect_refused([&] { bop_test_targets(root, "val"); }, root / "val", "missing split directory");
  for (const char* split : {"", ".", "..", "a/b"})
    EXPECT_THROW({ BopWriter bad(root, split); }, std::invalid_argument) << split;
}

// gray/ (BOP's folder of grey images) holds each image's ambient image, file for file.
TEST_F(BopTiny, GrayImagesAreTheAmbientImages) {
  for (int s = 1; s <= 2; ++s)
    for (int i = 0; i < 2; ++i) {
      const fs::path dir = root / "test" / ("00000" + std::to_string(s));
      const std::string name = "00000" + std::to_string(i) + ".png";
      ASSERT_TRUE(fs::exists(dir / "gray" / name)) << dir / "gray" / name;
      EXPECT_EQ(file_bytes(dir / "gray" / name), file_bytes(dir / "ambient" / name));
      const cv::Mat gray = cv::imread((dir / "gray" / name).string(), cv::IMREAD_UNCHANGED);
      ASSERT_EQ(gray.type(), CV_8UC1);
      EXPECT_EQ(
          cv::norm(gray, written[static_cast<size_t>(s - 1)][static_cast<size_t>(i)].frames.ambient, cv::NORM_INF), 0);
    }
}
