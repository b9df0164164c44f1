// mfc-teach: builds a part's template database (*.tdb) from its CAD model (paper Sec. 4.3).
//   mfc-teach MODEL --camera CAMERA.yaml --out PART.tdb [--obj-id N] [--name NAME]
//             [--unit mm|cm|m|in|<mm per unit>] [--chordal-tolerance MM] [--views K] [--symmetry none|z:N|z:inf]
//             [--views-symmetry none|z:N|z:inf] [--distance MM] [--lighting-turns N[:M]] [--lighting-tolerance PX]
//             [--lighting-band PX] [--threads N] [--quiet]
// Exit status: 0 written, 1 refused (model, camera, symmetry), 2 usage.
#include "tools/common/cli.hpp"
#include "vision/model/cad_reader.hpp"
#include "vision/model/mesh.hpp"
#include "vision/templates/template_teacher.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <string>

using namespace mfcd::vision;

namespace {

// What the command line sets; defaults as TeachParams has them, K = 300 views.
struct Options {
  std::vector<std::string> models;  // one MODEL: more are refused by name
  std::string camera, out, name, unit = "mm", symmetry = "none", views_symmetry, preview;
  int obj_id = -1, views = 300, threads = 0;
  int lighting_turns = TeachParams{}.lighting_turns, lighting_min_turns = TeachParams{}.lighting_min_turns;
  int lighting_tolerance = TeachParams{}.lighting_tolerance_px, lighting_band = TeachParams{}.lighting_band_px;
  double distance = 0;
  CadTessellation tessellation;
  bool quiet = false;
};

void add_options(CLI::App& app, Options& o) {
  app.add_option("MODEL", o.models, "part model: STL (ASCII/binary), OBJ, PLY, or STEP/IGES (tessellated by OCCT)")
      ->required()
      ->type_name("");
  app.add_option("--camera", o.camera, "camera + flash YAML the templates are rendered for (docs/camera.md)")
      ->required()
      ->type_name("FILE");
  app.add_option("--out", o.out, "template database to write")->required()->type_name("FILE");
  mfcd::tools::add_int(app, "--obj-id", o.obj_id, "BOP object id (default: N from a model named obj_00000N.*, else 1)");
  app.add_option("--name", o.name, "part name (default: the model file's stem)")->type_name("NAME");
  app.add_option("--unit", o.unit, "model unit: mm (default), cm, m, in, or mm per unit (STEP/IGES: from the file)")
      ->type_name("U");
  mfcd::tools::add_double(app, "--chordal-tolerance", o.tessellation.chordal_tolerance_mm,
                          "STEP/IGES: largest distance between a triangle and its surface\n(default 0.05)")
      ->type_name("MM");
  mfcd::tools::add_int(app, "--views", o.views, "views over the whole sphere (default 300)")->type_name("K");
  app.add_option("--symmetry", o.symmetry,
                 "none (default), z:N (N-fold about the model z axis), z:inf:\n"
                 "the turns that leave the part the same to the gripper")
      ->type_name("S");
  app.add_option("--views-symmetry", o.views_symmetry,
                 "the symmetry the views are folded by, when the part's edges\n"
                 "have a finer one (a small orienting feature); a subgroup of\n"
                 "--symmetry (default: --symmetry)")
      ->type_name("S");
  mfcd::tools::add_converted(
      app, "--distance", o.distance,
      [](const std::string& opt, const std::string& v) {
        const double d = mfcd::tools::parse_double(opt, v);
        if (!(d > 0)) throw mfcd::tools::UsageError(opt + " '" + v + "' is not a positive number");
        return d;
      },
      "part centre to lens (default: the camera's working_distance_mm)")
      ->type_name("MM");
  // N[:M]: N renders per view, M of them must show an edge pixel (M defaults to N).
  app.add_option_function<std::string>(
         "--lighting-turns",
         [&o](const std::string& v) {
           const size_t colon = v.find(':');
           o.lighting_turns = mfcd::tools::parse_int("--lighting-turns", v.substr(0, colon));
           o.lighting_min_turns = colon == std::string::npos
                                      ? o.lighting_turns
                                      : mfcd::tools::parse_int("--lighting-turns", v.substr(colon + 1));
         },
         "render each view N times, turned about the optical axis\n"
         "over the LED ring's period, and keep the edge pixels that at\n"
         "least M of them show (default 4:4; M defaults to N; 1 = off)")
      ->type_name("N[:M]");
  mfcd::tools::add_int(app, "--lighting-tolerance", o.lighting_tolerance,
                       "how far from the view's edge a turned render's may lie\n(default 1)")
      ->type_name("PX");
  mfcd::tools::add_int(app, "--lighting-band", o.lighting_band,
                       "light a turned render only this far from the view's edges\n(default 6; 0 = everywhere)")
      ->type_name("PX");
  mfcd::tools::add_int(app, "--threads", o.threads, "rendering threads (default: all cores)");
  app.add_option("--preview", o.preview, "also write a contact sheet of up to 64 views (lines over edge points)")
      ->type_name("PNG");
  app.add_flag("--quiet", o.quiet, "no progress bar");
}

// N for a model named like a BOP model, obj_00000N.ply; 1 otherwise. (Parsed by hand: std::regex
// trips GCC 12's -Wmaybe-uninitialized under ASan.)
int default_obj_id(const std::filesystem::path& model) {
  const std::string stem = model.stem().string();
  const std::string prefix = "obj_";
  if (stem.size() <= prefix.size() || stem.compare(0, prefix.size(), prefix) != 0) return 1;
  const std::string digits = stem.substr(prefix.size());
  if (digits.size() > 9 || digits.find_first_not_of("0123456789") != std::string::npos) return 1;
  return std::max(1, std::stoi(digits));
}

// A contact sheet of up to 64 views spread over the database: edge points grey, lines coloured by
// orientation channel. For checking a teach run by eye.
void write_preview(const TemplateDatabase& db, const std::string& file) {
  const int n = std::min<int>(64, static_cast<int>(db.views.size()));
  const int cols = 8, rows = (n + cols - 1) / cols;
  int cell = 0;
  for (const auto& v : db.views) cell = std::max(cell, v.lines.size.width);
  cv::Mat3b sheet(rows * cell, cols * cell, cv::Vec3b(0, 0, 0));
  for (int k = 0; k < n; ++k) {
    const auto& v = db.views[static_cast<size_t>(k) * db.views.size() / n];
    const cv::Point2f off(float((k % cols) * cell) + v.lines.origin.x, float((k / cols) * cell) + v.lines.origin.y);
    for (const auto& p : v.points) {
      const cv::Point q(cvRound(p.pixel.x + off.x), cvRound(p.pixel.y + off.y));
      if (q.inside(cv::Rect(0, 0, sheet.cols, sheet.rows))) sheet(q) = cv::Vec3b(90, 90, 90);
    }
    for (const auto& l : v.lines.lines) {
      cv::Mat3b hsv(1, 1, cv::Vec3b(static_cast<uchar>(l.channel * 180 / db.q), 255, 255)), bgr;
      cv::cvtColor(hsv, bgr, cv::COLOR_HSV2BGR);
      const cv::Point2f o = off - v.lines.origin;
      cv::line(sheet, l.a + o, l.b + o, cv::Scalar(bgr(0, 0)), 1, cv::LINE_AA);
    }
    cv::putText(sheet, std::to_string(v.index), cv::Point((k % cols) * cell + 3, (k / cols) * cell + 12),
                cv::FONT_HERSHEY_PLAIN, 0.9, cv::Scalar(255, 255, 255));
  }
  if (!cv::imwrite(file, sheet)) throw std::runtime_error(file + ": cannot write the preview image");
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Builds a part's template database (*.tdb) from its CAD model (docs/template-database.md).",
               "mfc-teach"};
  mfcd::tools::init_app(app);
  Options o;
  add_options(app, o);
  if (const auto code = mfcd::tools::parse(app, argc, argv)) return *code;
  const std::string& model = o.models.front();
  std::string name = o.name;
  int obj_id = o.obj_id;
  try {
    if (o.models.size() > 1)
      throw mfcd::tools::UsageError("more than one MODEL given ('" + o.models[0] + "', '" + o.models[1] + "')");
    if (obj_id < 0) obj_id = default_obj_id(model);
    if (obj_id < 1 || obj_id > 999999) throw mfcd::tools::UsageError("--obj-id must be in 1..999999");
    if (name.empty()) name = std::filesystem::path(model).stem().string();

    MeshLoadOptions mo;
    mo.unit_mm = parse_unit_mm(o.unit);
    mo.tessellation = o.tessellation;
    MeshReport report;
    const Mesh mesh = load_part(model, mo, &report);
    for (const auto& w : report.warnings)
      std::fprintf(stderr, "mfc-teach: %s: warning: %s\n", model.c_str(), w.c_str());
    const CameraConfig cam = load_camera_config(o.camera);

    TeachParams tp;
    tp.sphere_samples = o.views;
    tp.symmetry = PartSymmetry::parse(o.symmetry);
    // teach_templates refuses a fold that is not a subgroup of the part's symmetry.
    if (!o.views_symmetry.empty()) tp.views_symmetry = PartSymmetry::parse(o.views_symmetry);
    tp.distance_mm = o.distance;
    tp.threads = o.threads;
    tp.lighting_turns = o.lighting_turns;
    tp.lighting_min_turns = o.lighting_min_turns;
    tp.lighting_tolerance_px = o.lighting_tolerance;
    tp.lighting_band_px = o.lighting_band;
    const auto t0 = std::chrono::steady_clock::now();
    auto seconds = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
    const bool bar = !o.quiet;
    int last_percent = -1;
    TemplateDatabase db = teach_templates(mesh, cam, name, obj_id, tp, [&](int done, int total) {
      const int percent = total ? done * 100 / total : 100;
      if (!bar || percent == last_percent) return;
      last_percent = percent;
      const int width = 30, filled = total ? done * width / total : width;
      std::fprintf(stderr, "\rmfc-teach %s [%.*s%*s] %d/%d views %.1f s", name.c_str(), filled,
                   "##############################", width - filled, "", done, total, seconds());
      if (done == total) std::fputc('\n', stderr);
    });
    save_template_database(db, o.out);
    if (!o.preview.empty()) write_preview(db, o.preview);
    size_t lines = 0, points = 0;
    for (const auto& v : db.views) lines += v.lines.lines.size(), points += v.points.size();
    // The edge offset profiles within 10 degrees of the image axes (docs/template-database.md): the
    // views' and the query's differ by a few tenths of a pixel there, which the pose fit corrects.
    std::printf(
        "%s: part %s obj_id %d symmetry %s, views folded by %s: %zu views (K = %d), %.1f lines and %.0f edge points "
        "per view, "
        "distance %.1f mm, edge offset near image axes %.2f px (views) / %.2f px (query), lighting turns %d:%d, "
        "turns from the mesh: %s, %.1f s\n",
        o.out.c_str(), name.c_str(), obj_id, db.symmetry.str().c_str(), db.views_symmetry.str().c_str(),
        db.views.size(), o.views, double(lines) / db.views.size(), double(points) / db.views.size(), db.distance_mm,
        db.template_edge_offset.mean_near(0, 10), db.query_edge_offset.mean_near(0, 10), o.lighting_turns,
        o.lighting_min_turns, describe(db.turns).c_str(), seconds());
    return 0;
  } catch (const mfcd::tools::UsageError& e) {
    return mfcd::tools::usage_error(app, e.what());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "\nmfc-teach: %s\n", e.what());
    return 1;
  }
}
