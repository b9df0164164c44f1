// mfc-sim: drops parts into a simulated bin under the multi-flash camera, renders the
// flash images, applies the paper's corruptions and writes a BOP-format dataset (models and
// models_eval with vertex normals, the scenes, the split's BOP19 test targets).
// docs/datasets.md documents the output; `mfc-sim --help` the options. Exit status: 0 written,
// 1 failed (camera, meshes, writing), 2 usage.
#include "tools/common/cli.hpp"
#include "vision/dataset/bin_scene.hpp"
#include "vision/dataset/bop_dataset.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using namespace mfcd::vision;

namespace {

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  for (std::string item; std::getline(ss, item, sep);)
    if (!item.empty()) out.push_back(item);
  return out;
}

// Numbers as mfc-sim has always read them: to_int takes any number that is a whole one ("1e3").
double to_double(const std::string& opt, const std::string& v) {
  try {
    size_t used = 0;
    const double d = std::stod(v, &used);
    if (used == v.size()) return d;
  } catch (const std::exception&) {
  }
  throw mfcd::tools::UsageError(opt + ": '" + v + "' is not a number");
}

int to_int(const std::string& opt, const std::string& v) {
  const double d = to_double(opt, v);
  if (d != static_cast<int>(d)) throw mfcd::tools::UsageError(opt + ": '" + v + "' is not an integer");
  return static_cast<int>(d);
}

std::vector<fs::path> part_files(const std::string& arg) {
  std::vector<fs::path> files;
  if (fs::is_directory(arg)) {
    for (const auto& e : fs::directory_iterator(arg)) {
      std::string ext = e.path().extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
      if (e.is_regular_file() && (ext == ".stl" || ext == ".ply" || ext == ".obj")) files.push_back(e.path());
    }
    const std::vector<std::string> order = {"breaker", "diamond", "ellipse", "tnut", "knob", "wheel"};
    auto rank = [&](const fs::path& p) {
      const auto it = std::find(order.begin(), order.end(), p.stem().string());
      return std::pair(static_cast<int>(it - order.begin()), p.filename().string());
    };
    std::sort(files.begin(), files.end(), [&](const fs::path& a, const fs::path& b) { return rank(a) < rank(b); });
    if (files.empty()) throw mfcd::tools::UsageError("--parts: no .stl/.ply/.obj files in " + arg);
  } else {
    for (const auto& f : split(arg, ',')) files.emplace_back(f);
  }
  return files;
}

// The parts' meshes with their BOP ids (--obj-ids, else 1, 2, ... in file order).
std::vector<PartModel> load_models(const std::vector<fs::path>& files, const std::vector<int>& obj_ids) {
  if (!obj_ids.empty() && obj_ids.size() != files.size())
    throw mfcd::tools::UsageError("--obj-ids lists " + std::to_string(obj_ids.size()) + " ids for " +
                                  std::to_string(files.size()) + " parts");
  std::vector<PartModel> models;
  for (size_t k = 0; k < files.size(); ++k) {
    PartModel m;
    m.obj_id = obj_ids.empty() ? static_cast<int>(k) + 1 : obj_ids[k];
    if (m.obj_id < 1) throw mfcd::tools::UsageError("--obj-ids: ids must be positive");
    m.name = files[k].stem().string();
    m.mesh = load_mesh(files[k]);
    models.push_back(std::move(m));
  }
  return models;
}

// Seeds of different images must differ in every bit pattern the generators use.
uint64_t mix(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

// What the command line sets besides the simulator's options.
struct Options {
  std::string camera_file, parts_arg, out_dir, split_name = "test";
  int scenes = 1, images = 1;
  uint64_t seed = 1;
  std::vector<int> obj_ids;
  BinSceneOptions sim;
};

// The options that shape the bin and its corruption (BinSceneOptions).
void add_scene_options(CLI::App& app, BinSceneOptions& opt) {
  using mfcd::tools::add_converted;
  add_converted(app, "--parts-per-image", opt.parts_per_image, to_int, "parts dropped per image (default 6)")
      ->type_name("N");
  app.add_option_function<std::string>(
         "--bin",
         [&opt](const std::string& value) {
           const auto v = split(value, ',');
           if (v.size() != 3) throw mfcd::tools::UsageError("--bin needs X,Y,H");
           opt.bin.inner_x_mm = to_double("--bin", v[0]);
           opt.bin.inner_y_mm = to_double("--bin", v[1]);
           opt.bin.wall_height_mm = to_double("--bin", v[2]);
         },
         "inner bin size and wall height in mm (default 150,110,60)")
      ->type_name("X,Y,H");
  add_converted(app, "--max-occlusion", opt.max_occlusion, to_double,
                "reject drops leaving any part more occluded than F (default 1 = off)")
      ->type_name("F");
  add_converted(
      app, "--resting-weight", opt.resting_weight,
      [](const std::string&, const std::string& w) {
        if (w == "area") return BinSceneOptions::RestingWeight::support_area;
        if (w == "solid-angle") return BinSceneOptions::RestingWeight::solid_angle;
        throw mfcd::tools::UsageError("--resting-weight: '" + w + "' is neither area nor solid-angle");
      },
      "how a drop picks the face a part rests on: area (by support area,\n"
      "default) or solid-angle (by the solid angle at the centre of mass)")
      ->type_name("W");
  add_converted(app, "--max-lean", opt.max_lean_deg, to_double,
                "tilt each part's resting pose by up to DEG degrees (0-90, default 0):\n"
                "kept where the tilted part rests stably, i.e. leaning on others")
      ->type_name("DEG");
  app.add_flag_callback(
      "--no-corrupt", [&opt] { opt.missing.enabled = opt.clutter.enabled = false; },
      "neither missing edges nor clutter");
  app.add_flag_callback(
      "--no-missing-edges", [&opt] { opt.missing.enabled = false; }, "keep every depth edge");
  add_converted(app, "--missing-fraction", opt.missing.fraction, to_double,
                "share of found depth-edge pixels to remove (default 0.12)")
      ->type_name("F");
  app.add_flag_callback(
      "--no-clutter", [&opt] { opt.clutter.enabled = false; }, "no clutter rods");
  app.add_option_function<std::string>(
         "--clutter-rods",
         [&opt](const std::string& value) {
           const auto v = split(value, ',');
           if (v.size() != 2) throw mfcd::tools::UsageError("--clutter-rods needs MIN,MAX");
           opt.clutter.min_rods = to_int("--clutter-rods", v[0]);
           opt.clutter.max_rods = to_int("--clutter-rods", v[1]);
         },
         "clutter rods per image (default 6,12)")
      ->type_name("MIN,MAX");
}

void add_options(CLI::App& app, Options& o) {
  using mfcd::tools::add_converted;
  app.add_option("--camera", o.camera_file, "camera YAML (config/camera-sim.yaml)")->required()->type_name("FILE");
  app.add_option("--parts", o.parts_arg, "a folder of .stl/.ply/.obj meshes in mm, or a comma-separated list")
      ->required()
      ->type_name("DIR|FILES");
  app.add_option("--out", o.out_dir, "dataset root (created; existing scenes are overwritten)")
      ->required()
      ->type_name("DIR");
  add_converted(app, "--scenes", o.scenes, to_int, "number of scenes (default 1)")->type_name("S");
  add_converted(app, "--images-per-scene", o.images, to_int, "images per scene, each a new fill of the bin (default 1)")
      ->type_name("I");
  add_converted(
      app, "--seed", o.seed,
      [](const std::string& opt, const std::string& v) { return static_cast<uint64_t>(to_int(opt, v)); },
      "base seed (default 1); everything is deterministic in it")
      ->type_name("N");
  app.add_option_function<std::string>(
         "--obj-ids",
         [&o](const std::string& value) {
           for (const auto& id : split(value, ',')) o.obj_ids.push_back(to_int("--obj-ids", id));
         },
         "BOP object ids of the parts, in part order (default 1, 2, ...)")
      ->type_name("A,B,...");
  app.add_option("--split", o.split_name,
                 "split folder (default test); its BOP19 test targets go to\n"
                 "NAME_targets_bop19.json, less a _TYPE suffix\n"
                 "(test_x: test_targets_bop19.json)")
      ->type_name("NAME");
  add_scene_options(app, o.sim);
  app.footer(
      "Part order without --parts files: breaker, diamond, ellipse, tnut, knob, wheel (paper\n"
      "Table 1), then other names alphabetically; ids follow this order.");
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Drops parts into a simulated bin under the multi-flash camera, renders the flash images and\n"
      "writes a BOP-format dataset (docs/datasets.md).",
      "mfc-sim"};
  mfcd::tools::init_app(app);
  Options o;
  add_options(app, o);
  if (const auto code = mfcd::tools::parse(app, argc, argv)) return *code;
  const std::string &camera_file = o.camera_file, &out_dir = o.out_dir, &split_name = o.split_name;
  const int scenes = o.scenes, images = o.images;
  const BinSceneOptions& opt = o.sim;
  if (scenes < 1 || images < 1)
    return mfcd::tools::usage_error(app, "--scenes and --images-per-scene must be at least 1");

  try {
    const CameraConfig camera = load_camera_config(camera_file);
    const std::vector<PartModel> models = load_models(part_files(o.parts_arg), o.obj_ids);
    BinSimulator sim(camera, models, opt);
    BopWriter writer(out_dir, split_name);
    writer.write_models(models);
    writer.write_camera(camera);
    for (const auto& m : models) std::cout << "obj_id " << m.obj_id << " = " << m.name << '\n';

    const auto start = std::chrono::steady_clock::now();
    int total = 0, placed = 0, requested = 0;
    double occl_sum = 0, occl_max = 0, removed_sum = 0, added_sum = 0;
    for (int s = 0; s < scenes; ++s) {
      std::vector<SimulatedImage> ims;
      for (int i = 0; i < images; ++i) {
        std::fprintf(stderr, "\rmfc-sim: scene %d/%d image %d/%d", s + 1, scenes, i + 1, images);
        std::fflush(stderr);
        ims.push_back(sim.simulate(mix(o.seed ^ mix((static_cast<uint64_t>(s) << 32) | static_cast<uint64_t>(i)))));
        const SimulatedImage& im = ims.back();
        placed += static_cast<int>(im.instances.size());
        requested += opt.parts_per_image;
        for (const auto& inst : im.instances) {
          occl_sum += 1 - inst.visib_fract;
          occl_max = std::max(occl_max, 1 - inst.visib_fract);
        }
        removed_sum += im.corruption.removed_fraction;
        added_sum += im.corruption.added_fraction;
        ++total;
      }
      writer.write_scene(s + 1, camera, ims);
    }
    // Targets of every scene folder of the split, also those an earlier run left there.
    const auto targets = writer.write_test_targets();
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::fprintf(stderr, "\n");
    std::printf("wrote %s: %zu models, %d scenes x %d images in %s/ (%.2f s per image)\n", out_dir.c_str(),
                models.size(), scenes, images, split_name.c_str(), secs / total);
    std::printf(
        "parts placed %d of %d requested; occlusion mean %.1f %%, max %.1f %%; "
        "depth edges removed (measured) mean %.1f %%, added by the removal mean %.1f %%\n",
        placed, requested, placed ? 100 * occl_sum / placed : 0.0, 100 * occl_max, 100 * removed_sum / total,
        100 * added_sum / total);
    int target_instances = 0;
    for (const auto& t : targets) target_instances += t.inst_count;
    std::printf("%zu BOP19 test targets (%d instances at least %.0f %% visible) in %s\n", targets.size(),
                target_instances, 100 * kBopTargetMinVisibFract,
                (fs::path(out_dir) / bop_test_targets_filename(split_name)).c_str());
  } catch (const mfcd::tools::UsageError& e) {
    return mfcd::tools::usage_error(app, e.what());
  } catch (const std::exception& e) {
    std::cerr << "\nmfc-sim: " << e.what() << '\n';
    return 1;
  }
  return 0;
}
