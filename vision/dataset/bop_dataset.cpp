#include "vision/dataset/bop_dataset.hpp"

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <set>
#include <stdexcept>

namespace mfcd::vision {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string id6(int id) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%06d", id);
  return buf;
}

[[noreturn]] void fail(const fs::path& file, const std::string& reason) {
  throw std::runtime_error(file.string() + ": " + reason);
}

void write_json(const json& j, const fs::path& file) {
  std::ofstream out(file);
  out << j.dump(2) << '\n';
  if (!out) fail(file, "cannot write");
}

void write_png(const cv::Mat& image, const fs::path& file) {
  if (!cv::imwrite(file.string(), image)) fail(file, "cannot write PNG");
}

json matx(const cv::Matx33d& m) { return json(std::vector<double>(m.val, m.val + 9)); }
json vec(const cv::Vec3d& v) { return json{v[0], v[1], v[2]}; }
json rect(const cv::Rect& r) { return json{r.x, r.y, r.width, r.height}; }

json read_json(const fs::path& file) {
  std::ifstream in(file);
  if (!in) fail(file, fs::exists(file) ? "cannot read" : "missing file");
  try {
    return json::parse(in);
  } catch (const json::exception& e) {
    // parse_error, and out_of_range for a number beyond double's range (1e999).
    fail(file, std::string("bad JSON: ") + e.what());
  }
}

// Lookups that name the file and the key path on failure.
struct Reader {
  fs::path file;
  const json& key(const json& obj, const std::string& k, const std::string& where) const {
    if (!obj.is_object()) fail(file, where + " is not a JSON object");
    const auto it = obj.find(k);
    if (it == obj.end()) fail(file, "missing key '" + where + "." + k + "'");
    return *it;
  }
  double number(const json& j, const std::string& what) const {
    if (!j.is_number()) fail(file, "'" + what + "' is not a number");
    return j.get<double>();
  }
  // An integer in int's range (get<int> would wrap 4294967936 to 640).
  int integer(const json& j, const std::string& what) const {
    if (!j.is_number_integer()) fail(file, "'" + what + "' is not an integer");
    const bool fits = j.is_number_unsigned()
                          ? j.get<uint64_t>() <= static_cast<uint64_t>(std::numeric_limits<int>::max())
                          : j.get<int64_t>() >= std::numeric_limits<int>::min() &&
                                j.get<int64_t>() <= std::numeric_limits<int>::max();
    if (!fits) fail(file, "'" + what + "' = " + j.dump() + " is out of range");
    return j.get<int>();
  }
  // A number that must convert to int (a pixel coordinate or size): the conversion of one
  // outside int's range would be undefined.
  int pixels(double v, const std::string& what) const {
    if (!(v >= std::numeric_limits<int>::min() && v <= std::numeric_limits<int>::max()))
      fail(file, "'" + what + "' = " + std::to_string(v) + " is out of range");
    return static_cast<int>(v);
  }
  std::vector<double> numbers(const json& j, size_t n, const std::string& what) const {
    if (!j.is_array() || j.size() != n)
      fail(file, "'" + what + "' must be an array of " + std::to_string(n) + " numbers");
    std::vector<double> v;
    for (const auto& x : j) v.push_back(number(x, what));
    return v;
  }
  const json& image_entry(const json& scene, int image_id) const {
    return key(scene, std::to_string(image_id), "scene");
  }
};

cv::Matx33d to_matx(const std::vector<double>& v) { return cv::Matx33d(v.data()); }
cv::Vec3d to_vec(const std::vector<double>& v) { return {v[0], v[1], v[2]}; }

cv::Mat read_png(const fs::path& file, int type, const cv::Size& size, const std::string& sizes_from) {
  if (!fs::exists(file)) fail(file, "missing image");
  cv::Mat m = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
  if (m.empty()) fail(file, "unreadable image");
  if (m.type() != type)
    fail(file, std::string("expected a single-channel ") + (type == CV_16UC1 ? "16-bit" : "8-bit") + " image");
  if (m.size() != size)
    fail(file, "image size " + std::to_string(m.cols) + "x" + std::to_string(m.rows) + " differs from " +
                   std::to_string(size.width) + "x" + std::to_string(size.height) + " in " + sizes_from);
  return m;
}

// The scene ids of a split: its folders named by 6 digits, ascending.
std::vector<int> scene_ids_in(const fs::path& split_dir) {
  std::vector<int> ids;
  for (const auto& e : fs::directory_iterator(split_dir)) {
    const std::string n = e.path().filename().string();
    if (e.is_directory() && n.size() == 6 &&
        std::all_of(n.begin(), n.end(), [](char c) { return c >= '0' && c <= '9'; }))
      ids.push_back(std::stoi(n));
  }
  std::sort(ids.begin(), ids.end());
  return ids;
}

// A per-image key of a scene file ("0", "17") as an image id.
int image_id_of(const std::string& key, const fs::path& file) {
  int id = 0;
  const auto [end, ec] = std::from_chars(key.data(), key.data() + key.size(), id);
  if (key.empty() || key[0] == '-' || ec != std::errc() || end != key.data() + key.size())
    fail(file, "key '" + key + "' is not an image id");
  return id;
}

// One image's list of scene_gt.json; `w` is the image key, for messages.
std::vector<BopGtPose> gt_poses(const Reader& r, const json& list, const std::string& w) {
  if (!list.is_array()) fail(r.file, "'" + w + "' is not an array");
  std::vector<BopGtPose> out;
  for (size_t g = 0; g < list.size(); ++g) {
    const std::string wg = w + "[" + std::to_string(g) + "]";
    BopGtPose p;
    p.obj_id = r.integer(r.key(list[g], "obj_id", wg), wg + ".obj_id");
    p.R = to_matx(r.numbers(r.key(list[g], "cam_R_m2c", wg), 9, wg + ".cam_R_m2c"));
    p.t_mm = to_vec(r.numbers(r.key(list[g], "cam_t_m2c", wg), 3, wg + ".cam_t_m2c"));
    out.push_back(p);
  }
  return out;
}

// One image's list of scene_gt_info.json.
std::vector<BopGtInfo> gt_infos(const Reader& r, const json& list, const std::string& w) {
  if (!list.is_array()) fail(r.file, "'" + w + "' is not an array");
  std::vector<BopGtInfo> out;
  for (size_t g = 0; g < list.size(); ++g) {
    const std::string wg = w + "[" + std::to_string(g) + "]";
    auto box = [&](const char* k) {
      const std::string what = wg + "." + k;
      const auto v = r.numbers(r.key(list[g], k, wg), 4, what);
      return cv::Rect(r.pixels(v[0], what), r.pixels(v[1], what), r.pixels(v[2], what), r.pixels(v[3], what));
    };
    BopGtInfo i;
    i.bbox_obj = box("bbox_obj");
    i.bbox_visib = box("bbox_visib");
    i.px_count_all = r.integer(r.key(list[g], "px_count_all", wg), wg + ".px_count_all");
    i.px_count_valid = r.integer(r.key(list[g], "px_count_valid", wg), wg + ".px_count_valid");
    i.px_count_visib = r.integer(r.key(list[g], "px_count_visib", wg), wg + ".px_count_visib");
    i.visib_fract = r.number(r.key(list[g], "visib_fract", wg), wg + ".visib_fract");
    out.push_back(i);
  }
  return out;
}

void copy_into(const fs::path& from, const fs::path& to) {
  std::error_code ec;
  fs::copy_file(from, to, fs::copy_options::overwrite_existing, ec);
  if (ec) fail(to, "cannot copy " + from.string() + " here: " + ec.message());
}

}  // namespace

// ---------------------------------------------------------------------------------------
// Models

BopModelInfo compute_model_info(const PartModel& model) {
  BopModelInfo info;
  const cv::Vec3f lo = model.mesh.bbox_min(), hi = model.mesh.bbox_max();
  info.min = lo;
  info.size = hi - lo;
  // STL meshes repeat every vertex per triangle: measure the diameter on distinct points.
  std::vector<cv::Vec3f> pts = model.mesh.vertices;
  auto less = [](const cv::Vec3f& a, const cv::Vec3f& b) {
    return std::lexicographical_compare(a.val, a.val + 3, b.val, b.val + 3);
  };
  std::sort(pts.begin(), pts.end(), less);
  pts.erase(std::unique(pts.begin(), pts.end()), pts.end());
  double d2 = 0;
  for (size_t i = 0; i < pts.size(); ++i)
    for (size_t j = i + 1; j < pts.size(); ++j) {
      const cv::Vec3d d = cv::Vec3d(pts[i]) - cv::Vec3d(pts[j]);
      d2 = std::max(d2, d.dot(d));
    }
  info.diameter = std::sqrt(d2);
  info.symmetries_discrete = model.symmetries_discrete;
  info.symmetries_continuous = model.symmetries_continuous;
  return info;
}

std::vector<cv::Vec3f> vertex_normals(const Mesh& mesh) {
  std::vector<cv::Vec3d> sum(mesh.vertices.size(), cv::Vec3d(0, 0, 0));
  for (const auto& t : mesh.triangles) {
    for (uint32_t i : t)
      if (i >= mesh.vertices.size())
        throw std::invalid_argument("vertex_normals: triangle index " + std::to_string(i) + " is not one of the " +
                                    std::to_string(mesh.vertices.size()) + " vertices");
    const cv::Vec3d a(mesh.vertices[t[0]]), b(mesh.vertices[t[1]]), c(mesh.vertices[t[2]]);
    const cv::Vec3d n = (b - a).cross(c - a);  // |n| = twice the area: the weight; outward for CCW triangles
    for (uint32_t i : t) sum[i] += n;
  }
  std::vector<cv::Vec3f> out;
  out.reserve(sum.size());
  for (const auto& n : sum) {
    const double len = cv::norm(n);
    out.push_back(len > 0 ? cv::Vec3f(n / len) : cv::Vec3f(0, 0, 0));
  }
  return out;
}

void write_ply(const Mesh& mesh, const fs::path& file) {
  const std::vector<cv::Vec3f> normals = vertex_normals(mesh);
  std::ofstream out(file);
  if (!out) fail(file, "cannot create");
  out << "ply\nformat ascii 1.0\ncomment mfcd part model, millimetres, frame of the source mesh\n"
      << "comment vertex normals: area-weighted mean of the normals of the triangles using the vertex\n"
      << "element vertex " << mesh.vertices.size() << "\nproperty float x\nproperty float y\nproperty float z\n"
      << "property float nx\nproperty float ny\nproperty float nz\n"
      << "element face " << mesh.triangles.size() << "\nproperty list uchar int vertex_indices\nend_header\n";
  out.precision(9);
  for (size_t i = 0; i < mesh.vertices.size(); ++i) {
    const cv::Vec3f& v = mesh.vertices[i];
    const cv::Vec3f& n = normals[i];
    out << v[0] << ' ' << v[1] << ' ' << v[2] << ' ' << n[0] << ' ' << n[1] << ' ' << n[2] << '\n';
  }
  for (const auto& t : mesh.triangles) out << "3 " << t[0] << ' ' << t[1] << ' ' << t[2] << '\n';
  if (!out) fail(file, "cannot write");
}

// ---------------------------------------------------------------------------------------
// Writer

std::string bop_test_targets_filename(const std::string& split) {
  return split.substr(0, split.find('_')) + "_targets_bop19.json";
}

BopWriter::BopWriter(fs::path root, std::string split) : root_(std::move(root)), split_(std::move(split)) {
  if (split_.empty() || split_ == "." || split_ == ".." || split_.find('/') != std::string::npos)
    throw std::invalid_argument("split '" + split_ + "' is not a folder name (BOP's: test, val, train, test_TYPE)");
  fs::create_directories(root_ / split_);
}

fs::path BopWriter::scene_dir(int scene_id) const { return root_ / split_ / id6(scene_id); }

void BopWriter::write_models(const std::vector<PartModel>& models) {
  std::set<int> ids;
  for (const auto& m : models) {
    if (m.obj_id < 0)
      throw std::invalid_argument("model '" + m.name + "': object id " + std::to_string(m.obj_id) + " is negative");
    if (!ids.insert(m.obj_id).second)
      throw std::invalid_argument("model '" + m.name + "': object id " + std::to_string(m.obj_id) + " is used twice");
  }
  // BOP's evaluation reads models_eval/ (for its own datasets a uniformly resampled mesh); here
  // it holds the very files of models/, so scores are computed on the meshes that were rendered.
  const fs::path dir = root_ / "models", eval_dir = root_ / "models_eval";
  fs::create_directories(dir);
  fs::create_directories(eval_dir);
  json info = json::object();
  for (const auto& m : models) {
    const std::string name = "obj_" + id6(m.obj_id) + ".ply";
    write_ply(m.mesh, dir / name);
    copy_into(dir / name, eval_dir / name);
    const BopModelInfo mi = compute_model_info(m);
    json j = {{"diameter", mi.diameter}, {"min_x", mi.min[0]},   {"min_y", mi.min[1]},  {"min_z", mi.min[2]},
              {"size_x", mi.size[0]},    {"size_y", mi.size[1]}, {"size_z", mi.size[2]}};
    if (!mi.symmetries_discrete.empty()) {
      json list = json::array();
      for (const auto& T : mi.symmetries_discrete) list.push_back(std::vector<double>(T.val, T.val + 16));
      j["symmetries_discrete"] = list;
    }
    if (!mi.symmetries_continuous.empty()) {
      json list = json::array();
      for (const auto& s : mi.symmetries_continuous) list.push_back({{"axis", vec(s.axis)}, {"offset", vec(s.offset)}});
      j["symmetries_continuous"] = list;
    }
    info[std::to_string(m.obj_id)] = j;
  }
  write_json(info, dir / "models_info.json");
  copy_into(dir / "models_info.json", eval_dir / "models_info.json");
}

void BopWriter::write_camera(const CameraConfig& c) {
  const PinholeCamera& cam = c.camera;
  write_json({{"cx", cam.cx()},
              {"cy", cam.cy()},
              {"fx", cam.fx()},
              {"fy", cam.fy()},
              {"width", cam.image_size.width},
              {"height", cam.image_size.height},
              {"depth_scale", kBopDepthScale}},
             root_ / "camera.json");
}

void BopWriter::write_capture(int scene_id, const CameraConfig& camera, const MfcFrames& frames,
                              const std::vector<BopGtPose>& truth) {
  const fs::path dir = scene_dir(scene_id);
  if (frames.flash.size() != camera.flashes.positions_mm.size())
    fail(dir, "the capture has " + std::to_string(frames.flash.size()) + " flash images for " +
                  std::to_string(camera.flashes.positions_mm.size()) + " LEDs");
  for (const char* sub : {"flash", "ambient", "gray"}) fs::create_directories(dir / sub);
  json flashes = json::array();
  for (const auto& p : camera.flashes.positions_mm) flashes.push_back(vec(p));
  json cam = {{"cam_K", matx(camera.camera.K)},
              {"depth_scale", kBopDepthScale},
              {"width", camera.camera.image_size.width},
              {"height", camera.camera.image_size.height},
              {"flash_positions_mm", flashes}};
  if (camera.working_distance_mm > 0) cam["working_distance_mm"] = camera.working_distance_mm;
  json gt = json::array();
  for (const BopGtPose& p : truth)
    gt.push_back({{"obj_id", p.obj_id}, {"cam_R_m2c", matx(p.R)}, {"cam_t_m2c", vec(p.t_mm)}});
  const std::string iid = id6(0);
  for (size_t k = 0; k < frames.flash.size(); ++k)
    write_png(frames.flash[k], dir / "flash" / (iid + "_" + std::to_string(k) + ".png"));
  write_png(frames.ambient, dir / "ambient" / (iid + ".png"));
  copy_into(dir / "ambient" / (iid + ".png"), dir / "gray" / (iid + ".png"));
  write_json(json::object({{"0", cam}}), dir / "scene_camera.json");
  write_json(json::object({{"0", gt}}), dir / "scene_gt.json");
}

void BopWriter::write_scene(int scene_id, const CameraConfig& camera, const std::vector<SimulatedImage>& images) {
  const fs::path dir = scene_dir(scene_id);
  for (const char* sub : {"flash", "ambient", "gray", "depth", "mask", "mask_visib"}) fs::create_directories(dir / sub);
  json cams = json::object(), gts = json::object(), infos = json::object(), corr = json::object();
  json flashes = json::array();
  for (const auto& p : camera.flashes.positions_mm) flashes.push_back(vec(p));
  for (size_t i = 0; i < images.size(); ++i) {
    const SimulatedImage& im = images[i];
    const std::string key = std::to_string(i), iid = id6(static_cast<int>(i));
    cams[key] = {{"cam_K", matx(camera.camera.K)},          {"depth_scale", kBopDepthScale},
                 {"width", camera.camera.image_size.width}, {"height", camera.camera.image_size.height},
                 {"flash_positions_mm", flashes},           {"working_distance_mm", camera.working_distance_mm}};
    json gt = json::array(), info = json::array();
    for (size_t g = 0; g < im.instances.size(); ++g) {
      const PartInstance& p = im.instances[g];
      gt.push_back({{"obj_id", p.obj_id}, {"cam_R_m2c", matx(p.R)}, {"cam_t_m2c", vec(p.t_mm)}});
      info.push_back({{"bbox_obj", rect(p.bbox_obj)},
                      {"bbox_visib", rect(p.bbox_visib)},
                      {"px_count_all", p.px_count_all},
                      {"px_count_valid", p.px_count_valid},
                      {"px_count_visib", p.px_count_visib},
                      {"visib_fract", p.visib_fract}});
      const std::string gid = iid + "_" + id6(static_cast<int>(g)) + ".png";
      write_png(p.mask_all, dir / "mask" / gid);
      write_png(p.mask_visib, dir / "mask_visib" / gid);
    }
    gts[key] = gt;
    infos[key] = info;
    const CorruptionReport& c = im.corruption;
    corr[key] = {{"true_edge_px", c.true_edge_px},
                 {"recall_clean", c.recall_clean},
                 {"recall_corrupted", c.recall_corrupted},
                 {"removed_fraction", c.removed_fraction},
                 {"stretches", c.stretches},
                 {"added_fraction", c.added_fraction},
                 {"clutter_rods", c.clutter_rods}};
    if (im.frames.flash.size() != camera.flashes.positions_mm.size())
      fail(dir, "image " + key + " has " + std::to_string(im.frames.flash.size()) + " flash images for " +
                    std::to_string(camera.flashes.positions_mm.size()) + " LEDs");
    for (size_t k = 0; k < im.frames.flash.size(); ++k)
      write_png(im.frames.flash[k], dir / "flash" / (iid + "_" + std::to_string(k) + ".png"));
    write_png(im.frames.ambient, dir / "ambient" / (iid + ".png"));
    // gray/ is BOP's folder of grey images (ITODD's): the toolkit's scripts find the image there.
    copy_into(dir / "ambient" / (iid + ".png"), dir / "gray" / (iid + ".png"));
    cv::Mat1w depth(im.depth_mm.size());
    for (int y = 0; y < depth.rows; ++y)
      for (int x = 0; x < depth.cols; ++x)
        depth(y, x) = cv::saturate_cast<uint16_t>(std::lround(im.depth_mm(y, x) / kBopDepthScale));
    write_png(depth, dir / "depth" / (iid + ".png"));
  }
  write_json(cams, dir / "scene_camera.json");
  write_json(gts, dir / "scene_gt.json");
  write_json(infos, dir / "scene_gt_info.json");
  write_json(corr, dir / "scene_mfc_corruption.json");
}

std::vector<BopTestTarget> BopWriter::write_test_targets() const {
  const std::vector<BopTestTarget> targets = bop_test_targets(root_, split_);
  json list = json::array();
  for (const auto& t : targets)
    list.push_back({{"scene_id", t.scene_id}, {"im_id", t.im_id}, {"obj_id", t.obj_id}, {"inst_count", t.inst_count}});
  write_json(list, root_ / bop_test_targets_filename(split_));
  return targets;
}

std::vector<BopTestTarget> bop_test_targets(const fs::path& root, const std::string& split) {
  const fs::path split_dir = root / split;
  if (!fs::is_directory(split_dir)) fail(split_dir, "missing split directory");
  std::vector<BopTestTarget> targets;
  for (int scene : scene_ids_in(split_dir)) {
    const fs::path gt_file = split_dir / id6(scene) / "scene_gt.json";
    const fs::path info_file = split_dir / id6(scene) / "scene_gt_info.json";
    const json gt = read_json(gt_file), info = read_json(info_file);
    const Reader rg{gt_file}, ri{info_file};
    if (!gt.is_object()) fail(gt_file, "top level is not a JSON object");
    std::map<int, std::string> keys;  // image id -> key, ascending
    for (const auto& [key, v] : gt.items()) keys[image_id_of(key, gt_file)] = key;
    for (const auto& [im, key] : keys) {
      const std::vector<BopGtPose> poses = gt_poses(rg, gt[key], key);
      const std::vector<BopGtInfo> infos = gt_infos(ri, ri.key(info, key, "scene"), key);
      if (infos.size() != poses.size())
        fail(info_file, "'" + key + "' lists " + std::to_string(infos.size()) + " instances, " + gt_file.string() +
                            " lists " + std::to_string(poses.size()));
      const size_t first = targets.size();
      for (size_t g = 0; g < poses.size(); ++g) {
        if (!(infos[g].visib_fract >= kBopTargetMinVisibFract)) continue;
        auto it = std::find_if(targets.begin() + static_cast<long>(first), targets.end(),
                               [&](const BopTestTarget& t) { return t.obj_id == poses[g].obj_id; });
        if (it == targets.end())
          targets.push_back({scene, im, poses[g].obj_id, 1});
        else
          ++it->inst_count;
      }
    }
  }
  return targets;
}

// ---------------------------------------------------------------------------------------
// Reader

CameraConfig BopSceneCamera::config() const {
  CameraConfig c;
  c.camera.image_size = image_size;
  c.camera.K = K;
  c.camera.distortion = {0, 0, 0, 0, 0};
  c.flashes.ring.reset();
  c.flashes.positions_mm = flash_positions_mm;
  if (working_distance_mm > 0) c.working_distance_mm = working_distance_mm;
  return c;
}

BopDataset::BopDataset(fs::path root, std::string split, BopCameraDefaults defaults)
    : root_(std::move(root)), split_dir_(root_ / split), defaults_(std::move(defaults)) {
  if (!fs::is_directory(root_)) fail(root_, "not a directory");
  if (!fs::is_directory(split_dir_)) fail(split_dir_, "missing split directory");
  read_dataset_camera();
  const fs::path file = root_ / "models" / "models_info.json";
  const json j = read_json(file);
  const Reader r{file};
  if (!j.is_object()) fail(file, "top level is not a JSON object");
  for (const auto& [key, m] : j.items()) {
    int id = 0;
    try {
      size_t used = 0;
      id = std::stoi(key, &used);
      if (used != key.size()) throw std::invalid_argument(key);
    } catch (const std::exception&) {
      fail(file, "key '" + key + "' is not an object id");
    }
    BopModelInfo info;
    info.diameter = r.number(r.key(m, "diameter", key), key + ".diameter");
    const char* axes = "xyz";
    for (int k = 0; k < 3; ++k) {
      const std::string mn = std::string("min_") + axes[k], sz = std::string("size_") + axes[k];
      info.min[k] = r.number(r.key(m, mn, key), key + "." + mn);
      info.size[k] = r.number(r.key(m, sz, key), key + "." + sz);
    }
    if (m.contains("symmetries_discrete")) {
      const json& list = m["symmetries_discrete"];
      if (!list.is_array()) fail(file, "'" + key + ".symmetries_discrete' is not an array");
      for (const auto& T : list)
        info.symmetries_discrete.push_back(cv::Matx44d(r.numbers(T, 16, key + ".symmetries_discrete").data()));
    }
    if (m.contains("symmetries_continuous")) {
      const json& list = m["symmetries_continuous"];
      if (!list.is_array()) fail(file, "'" + key + ".symmetries_continuous' is not an array");
      for (const auto& s : list) {
        const std::string w = key + ".symmetries_continuous";
        info.symmetries_continuous.push_back({to_vec(r.numbers(r.key(s, "axis", w), 3, w + ".axis")),
                                              to_vec(r.numbers(r.key(s, "offset", w), 3, w + ".offset"))});
      }
    }
    models_info_[id] = info;
  }
}

void BopDataset::read_dataset_camera() {
  const fs::path file = root_ / "camera.json";
  if (!fs::exists(file)) return;
  const json j = read_json(file);
  const Reader r{file};
  if (!j.is_object()) fail(file, "top level is not a JSON object");
  dataset_camera_.present = true;
  if (j.contains("width") || j.contains("height"))
    dataset_camera_.image_size =
        cv::Size(r.integer(r.key(j, "width", "camera"), "width"), r.integer(r.key(j, "height", "camera"), "height"));
  if (j.contains("depth_scale")) dataset_camera_.depth_scale = r.number(j["depth_scale"], "depth_scale");
}

fs::path BopDataset::scene_dir(int scene_id) const { return split_dir_ / id6(scene_id); }

fs::path BopDataset::model_path(int obj_id) const {
  const fs::path p = root_ / "models" / ("obj_" + id6(obj_id) + ".ply");
  if (!models_info_.count(obj_id)) fail(root_ / "models" / "models_info.json", "no object " + std::to_string(obj_id));
  if (!fs::exists(p)) fail(p, "missing model file");
  return p;
}

std::vector<int> BopDataset::scenes() const { return scene_ids_in(split_dir_); }

std::vector<int> BopDataset::images(int scene_id) const {
  const fs::path file = scene_dir(scene_id) / "scene_camera.json";
  const json j = read_json(file);
  if (!j.is_object()) fail(file, "top level is not a JSON object");
  std::vector<int> ids;
  for (const auto& [key, v] : j.items()) ids.push_back(image_id_of(key, file));
  std::sort(ids.begin(), ids.end());
  return ids;
}

BopSceneCamera BopDataset::camera(int scene_id, int image_id) const {
  const fs::path file = scene_dir(scene_id) / "scene_camera.json";
  const json j = read_json(file);
  const Reader r{file};
  const std::string w = std::to_string(image_id);
  const json& e = r.image_entry(j, image_id);
  if (!e.is_object()) fail(file, "'" + w + "' is not a JSON object");
  const DatasetCamera& d = dataset_camera_;
  // The entry's own key, else camera.json's value, else a refusal naming both places.
  auto missing = [&](const std::string& k, const char* fallback) {
    fail(file, "missing key '" + w + "." + k + "', and " + (root_ / "camera.json").string() +
                   (d.present ? " gives no " : " does not exist to give the ") + fallback);
  };
  BopSceneCamera c;
  c.K = to_matx(r.numbers(r.key(e, "cam_K", w), 9, w + ".cam_K"));
  if (e.contains("depth_scale"))
    c.depth_scale = r.number(e["depth_scale"], w + ".depth_scale");
  else if (d.depth_scale)
    c.depth_scale = *d.depth_scale;
  else
    missing("depth_scale", "depth_scale");
  if (e.contains("width") || e.contains("height"))
    c.image_size = {r.integer(r.key(e, "width", w), w + ".width"), r.integer(r.key(e, "height", w), w + ".height")};
  else if (d.image_size)
    c.image_size = *d.image_size;
  else
    missing("width", "width and height");
  if (c.image_size.width <= 0 || c.image_size.height <= 0) fail(file, "'" + w + "' image size must be positive");
  if (c.depth_scale <= 0) fail(file, "'" + w + ".depth_scale' must be positive");
  if (c.K(0, 0) <= 0 || c.K(1, 1) <= 0 || c.K(2, 2) != 1 || c.K(2, 0) != 0 || c.K(2, 1) != 0)
    fail(file, "'" + w + ".cam_K' is not a pinhole matrix (fx, fy > 0, last row 0 0 1)");
  if (c.K(0, 2) < -0.5 || c.K(0, 2) > c.image_size.width - 0.5 || c.K(1, 2) < -0.5 ||
      c.K(1, 2) > c.image_size.height - 0.5)
    fail(file, "'" + w + ".cam_K' principal point lies outside the " + std::to_string(c.image_size.width) + "x" +
                   std::to_string(c.image_size.height) + " image");
  if (e.contains("flash_positions_mm")) {
    const json& flashes = e["flash_positions_mm"];
    if (!flashes.is_array() || flashes.empty()) fail(file, "'" + w + ".flash_positions_mm' must be a non-empty array");
    for (const auto& p : flashes) c.flash_positions_mm.push_back(to_vec(r.numbers(p, 3, w + ".flash_positions_mm")));
  } else if (!defaults_.flash_positions_mm.empty()) {
    c.flash_positions_mm = defaults_.flash_positions_mm;
  } else {
    fail(file, "missing key '" + w +
                   ".flash_positions_mm': the dataset does not say where the LEDs are; give the "
                   "camera file whose flashes took its images (--camera)");
  }
  if (e.contains("working_distance_mm"))
    c.working_distance_mm = r.number(e["working_distance_mm"], w + ".working_distance_mm");
  if (e.contains("cam_R_w2c") || e.contains("cam_t_w2c")) {
    c.has_world_pose = true;
    c.R_w2c = to_matx(r.numbers(r.key(e, "cam_R_w2c", w), 9, w + ".cam_R_w2c"));
    c.t_w2c_mm = to_vec(r.numbers(r.key(e, "cam_t_w2c", w), 3, w + ".cam_t_w2c"));
    // A rotation: orthonormal rows, determinant +1 (to the precision of a JSON file's decimals).
    if (cv::norm(c.R_w2c * c.R_w2c.t() - cv::Matx33d::eye()) > 1e-5 || cv::determinant(c.R_w2c) < 0)
      fail(file, "'" + w + ".cam_R_w2c' is not a rotation");
  }
  return c;
}

std::vector<BopGtPose> BopDataset::ground_truth(int scene_id, int image_id) const {
  const fs::path file = scene_dir(scene_id) / "scene_gt.json";
  const json j = read_json(file);
  const Reader r{file};
  return gt_poses(r, r.image_entry(j, image_id), std::to_string(image_id));
}

std::vector<BopGtInfo> BopDataset::ground_truth_info(int scene_id, int image_id) const {
  const fs::path file = scene_dir(scene_id) / "scene_gt_info.json";
  const json j = read_json(file);
  const Reader r{file};
  return gt_infos(r, r.image_entry(j, image_id), std::to_string(image_id));
}

MfcFrames BopDataset::frames(int scene_id, int image_id) const {
  const BopSceneCamera cam = camera(scene_id, image_id);
  const fs::path dir = scene_dir(scene_id);
  const std::string iid = id6(image_id);
  const std::string from = (dir / "scene_camera.json").string();
  MfcFrames f;
  const size_t n = cam.flash_positions_mm.size();
  for (size_t k = 0; k < n; ++k) {
    const fs::path p = dir / "flash" / (iid + "_" + std::to_string(k) + ".png");
    if (!fs::exists(p))
      fail(p, "missing flash image: scene_camera.json lists " + std::to_string(n) + " flash positions");
    f.flash.push_back(read_png(p, CV_8UC1, cam.image_size, from));
  }
  const fs::path extra = dir / "flash" / (iid + "_" + std::to_string(n) + ".png");
  if (fs::exists(extra))
    fail(extra, "more flash images than the " + std::to_string(n) + " flash positions in scene_camera.json");
  f.ambient = read_png(dir / "ambient" / (iid + ".png"), CV_8UC1, cam.image_size, from);
  return f;
}

cv::Mat1f BopDataset::depth_mm(int scene_id, int image_id) const {
  const BopSceneCamera cam = camera(scene_id, image_id);
  const fs::path dir = scene_dir(scene_id);
  const cv::Mat raw = read_png(dir / "depth" / (id6(image_id) + ".png"), CV_16UC1, cam.image_size,
                               (dir / "scene_camera.json").string());
  cv::Mat1f d;
  raw.convertTo(d, CV_32F, cam.depth_scale);
  return d;
}

cv::Mat1b BopDataset::mask_visib(int scene_id, int image_id, int instance) const {
  return mask_png("mask_visib", scene_id, image_id, instance);
}

cv::Mat1b BopDataset::mask(int scene_id, int image_id, int instance) const {
  return mask_png("mask", scene_id, image_id, instance);
}

cv::Mat1b BopDataset::mask_png(const char* folder, int scene_id, int image_id, int instance) const {
  const BopSceneCamera cam = camera(scene_id, image_id);
  const fs::path dir = scene_dir(scene_id);
  return read_png(dir / folder / (id6(image_id) + "_" + id6(instance) + ".png"), CV_8UC1, cam.image_size,
                  (dir / "scene_camera.json").string());
}

}  // namespace mfcd::vision
