// mfc-sim: drops parts into a simulated bin under the multi-flash camera, renders the
// flash images, applies the paper's corruptions and writes a BOP-format dataset (models and
// models_eval with vertex normals, the scenes, the split's BOP19 test targets).
// docs/datasets.md documents the output; `mfc-sim --help` the options.
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

const char* kUsage = R"(usage: mfc-sim --camera FILE --parts DIR|FILE[,FILE...] --out DIR [options]

  --camera FILE            camera YAML (config/camera-sim.yaml)
  --parts DIR|FILES        a folder of .stl/.ply/.obj meshes in mm, or a comma-separated list
  --out DIR                dataset root (created; existing scenes are overwritten)
  --scenes S               number of scenes (default 1)
  --images-per-scene I     images per scene, each a new fill of the bin (default 1)
  --parts-per-image N      parts dropped per image (default 6)
  --seed N                 base seed (default 1); everything is deterministic in it
  --obj-ids A,B,...        BOP object ids of the parts, in part order (default 1, 2, ...)
  --split NAME             split folder (default test); its BOP19 test targets go to
                           NAME_targets_bop19.json, less a _TYPE suffix (test_x: test_targets_bop19.json)
  --bin X,Y,H              inner bin size and wall height in mm (default 150,110,60)
  --max-occlusion F        reject drops leaving any part more occluded than F (default 1 = off)
  --resting-weight W       how a drop picks the face a part rests on: area (by support area,
                           default) or solid-angle (by the solid angle at the centre of mass)
  --max-lean DEG           tilt each part's resting pose by up to DEG degrees (0-90, default 0):
                           kept where the tilted part rests stably, i.e. leaning on others
  --no-corrupt             neither missing edges nor clutter
  --no-missing-edges       keep every depth edge
  --missing-fraction F     share of found depth-edge pixels to remove (default 0.12)
  --no-clutter             no clutter rods
  --clutter-rods MIN,MAX   clutter rods per image (default 6,12)
Part order without --parts files: breaker, diamond, ellipse, tnut, knob, wheel (paper
Table 1), then other names alphabetically; ids follow this order.
)";

[[noreturn]] void usage_error(const std::string& msg) {
  std::cerr << "mfc-sim: " << msg << "\n\n" << kUsage;
  std::exit(2);
}

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  for (std::string item; std::getline(ss, item, sep);)
    if (!item.empty()) out.push_back(item);
  return out;
}

double to_double(const std::string& opt, const std::string& v) {
  try {
    size_t used = 0;
    const double d = std::stod(v, &used);
    if (used == v.size()) return d;
  } catch (const std::exception&) {
  }
  usage_error(opt + ": '" + v + "' is not a number");
}

int to_int(const std::string& opt, const std::string& v) {
  const double d = to_double(opt, v);
  if (d != static_cast<int>(d)) usage_error(opt + ": '" + v + "' is not an integer");
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
    if (files.empty()) usage_error("--parts: no .stl/.ply/.obj files in " + arg);
  } else {
    for (const auto& f : split(arg, ',')) files.emplace_back(f);
  }
  return files;
}

// Seeds of different images must differ in every bit pattern the generators use.
uint64_t mix(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

}  // namespace

int main(int argc, char** argv) {
  std::string camera_file, parts_arg, out_dir, split_name = "test";
  int scenes = 1, images = 1;
  uint64_t seed = 1;
  std::vector<int> obj_ids;
  BinSceneOptions opt;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage_error(a + " needs a value");
      return argv[++i];
    };
    if (a == "--help" || a == "-h") {
      std::cout << kUsage;
      return 0;
    } else if (a == "--camera") camera_file = value();
    else if (a == "--parts") parts_arg = value();
    else if (a == "--out") out_dir = value();
    else if (a == "--scenes") scenes = to_int(a, value());
    else if (a == "--images-per-scene") images = to_int(a, value());
    else if (a == "--parts-per-image") opt.parts_per_image = to_int(a, value());
    else if (a == "--seed") seed = static_cast<uint64_t>(to_int(a, value()));
    else if (a == "--split") split_name = value();
    else if (a == "--obj-ids") {
      for (const auto& s : split(value(), ',')) obj_ids.push_back(to_int(a, s));
    } else if (a == "--bin") {
      const auto v = split(value(), ',');
      if (v.size() != 3) usage_error("--bin needs X,Y,H");
      opt.bin.inner_x_mm = to_double(a, v[0]);
      opt.bin.inner_y_mm = to_double(a, v[1]);
      opt.bin.wall_height_mm = to_double(a, v[2]);
    } else if (a == "--max-occlusion") opt.max_occlusion = to_double(a, value());
    else if (a == "--max-lean") opt.max_lean_deg = to_double(a, value());
    else if (a == "--resting-weight") {
      const std::string w = value();
      if (w == "area") opt.resting_weight = BinSceneOptions::RestingWeight::support_area;
      else if (w == "solid-angle") opt.resting_weight = BinSceneOptions::RestingWeight::solid_angle;
      else usage_error("--resting-weight: '" + w + "' is neither area nor solid-angle");
    }
    else if (a == "--no-corrupt") opt.missing.enabled = opt.clutter.enabled = false;
    else if (a == "--no-missing-edges") opt.missing.enabled = false;
    else if (a == "--missing-fraction") opt.missing.fraction = to_double(a, value());
    else if (a == "--no-clutter") opt.clutter.enabled = false;
    else if (a == "--clutter-rods") {
      const auto v = split(value(), ',');
      if (v.size() != 2) usage_error("--clutter-rods needs MIN,MAX");
      opt.clutter.min_rods = to_int(a, v[0]);
      opt.clutter.max_rods = to_int(a, v[1]);
    } else usage_error("unknown option " + a);
  }
  if (camera_file.empty() || parts_arg.empty() || out_dir.empty()) usage_error("--camera, --parts and --out are required");
  if (scenes < 1 || images < 1) usage_error("--scenes and --images-per-scene must be at least 1");

  try {
    const CameraConfig camera = load_camera_config(camera_file);
    const auto files = part_files(parts_arg);
    if (!obj_ids.empty() && obj_ids.size() != files.size())
      usage_error("--obj-ids lists " + std::to_string(obj_ids.size()) + " ids for " + std::to_string(files.size()) + " parts");
    std::vector<PartModel> models;
    for (size_t k = 0; k < files.size(); ++k) {
      PartModel m;
      m.obj_id = obj_ids.empty() ? static_cast<int>(k) + 1 : obj_ids[k];
      if (m.obj_id < 1) usage_error("--obj-ids: ids must be positive");
      m.name = files[k].stem().string();
      m.mesh = load_mesh(files[k]);
      models.push_back(std::move(m));
    }
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
        ims.push_back(sim.simulate(mix(seed ^ mix((static_cast<uint64_t>(s) << 32) | static_cast<uint64_t>(i)))));
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
    std::printf("parts placed %d of %d requested; occlusion mean %.1f %%, max %.1f %%; "
                "depth edges removed (measured) mean %.1f %%, added by the removal mean %.1f %%\n",
                placed, requested, placed ? 100 * occl_sum / placed : 0.0, 100 * occl_max,
                100 * removed_sum / total, 100 * added_sum / total);
    int target_instances = 0;
    for (const auto& t : targets) target_instances += t.inst_count;
    std::printf("%zu BOP19 test targets (%d instances at least %.0f %% visible) in %s\n", targets.size(),
                target_instances, 100 * kBopTargetMinVisibFract,
                (fs::path(out_dir) / bop_test_targets_filename(split_name)).c_str());
  } catch (const std::exception& e) {
    std::cerr << "\nmfc-sim: " << e.what() << '\n';
    return 1;
  }
  return 0;
}
