// mfc-teach: builds a part's template database (*.tdb) from its CAD model (paper Sec. 4.3).
//   mfc-teach MODEL --camera CAMERA.yaml --out PART.tdb [--obj-id N] [--name NAME]
//             [--unit mm|cm|m|in|<mm per unit>] [--views K] [--symmetry none|z:N|z:inf]
//             [--views-symmetry none|z:N|z:inf] [--distance MM] [--lighting-turns N[:M]] [--lighting-tolerance PX] [--threads N] [--quiet]
#include "tools/common/cli_numbers.hpp"
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

void usage(std::FILE* to) {
  std::fprintf(to,
               "usage: mfc-teach MODEL --camera CAMERA.yaml --out PART.tdb [options]\n"
               "  MODEL              part mesh: STL (ASCII/binary), OBJ or PLY\n"
               "  --camera FILE      camera + flash YAML the templates are rendered for (docs/camera.md)\n"
               "  --out FILE         template database to write\n"
               "  --obj-id N         BOP object id (default: N from a model named obj_00000N.*, else 1)\n"
               "  --name NAME        part name (default: the model file's stem)\n"
               "  --unit U           model unit: mm (default), cm, m, in, or mm per unit\n"
               "  --views K          views over the whole sphere (default 300)\n"
               "  --symmetry S       none (default), z:N (N-fold about the model z axis), z:inf:\n"
               "                     the turns that leave the part the same to the gripper\n"
               "  --views-symmetry S the symmetry the views are folded by, when the part's edges\n"
               "                     have a finer one (a small orienting feature); a subgroup of\n"
               "                     --symmetry (default: --symmetry)\n"
               "  --distance MM      part centre to lens (default: the camera's working_distance_mm)\n"
               "  --lighting-turns N[:M] render each view N times, turned about the optical axis\n"
               "                     over the LED ring's period, and keep the edge pixels that at\n"
               "                     least M of them show (default 4:4; M defaults to N; 1 = off)\n"
               "  --lighting-tolerance PX  how far from the view's edge a turned render's may lie\n"
               "                     (default 1)\n"
               "  --threads N        rendering threads (default: all cores)\n"
               "  --preview PNG      also write a contact sheet of up to 64 views (lines over edge points)\n"
               "  --quiet            no progress bar\n");
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
  std::string model, camera, out, name, unit = "mm", symmetry = "none", views_symmetry;
  const TeachParams defaults;
  int obj_id = -1, views = 300, threads = 0, lighting_turns = defaults.lighting_turns,
      lighting_min_turns = defaults.lighting_min_turns, lighting_tolerance = defaults.lighting_tolerance_px;
  double distance = 0;
  bool quiet = false;
  std::string preview;
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      auto value = [&](const char* opt) -> std::string {
        if (i + 1 >= argc) throw std::invalid_argument(std::string(opt) + " needs a value");
        return argv[++i];
      };
      auto integer = [&](const char* opt) { return mfcd::tools::parse_int(opt, value(opt)); };
      if (a == "-h" || a == "--help") {
        usage(stdout);
        return 0;
      } else if (a == "--camera") camera = value("--camera");
      else if (a == "--out") out = value("--out");
      else if (a == "--obj-id") obj_id = integer("--obj-id");
      else if (a == "--name") name = value("--name");
      else if (a == "--unit") unit = value("--unit");
      else if (a == "--views") views = integer("--views");
      else if (a == "--symmetry") symmetry = value("--symmetry");
      else if (a == "--views-symmetry") views_symmetry = value("--views-symmetry");
      else if (a == "--threads") threads = integer("--threads");
      else if (a == "--lighting-tolerance") lighting_tolerance = integer("--lighting-tolerance");
      else if (a == "--lighting-turns") {
        const std::string v = value("--lighting-turns");
        const size_t colon = v.find(':');
        lighting_turns = mfcd::tools::parse_int("--lighting-turns", v.substr(0, colon));
        lighting_min_turns =
            colon == std::string::npos ? lighting_turns : mfcd::tools::parse_int("--lighting-turns", v.substr(colon + 1));
      }
      else if (a == "--distance") {
        const std::string v = value("--distance");
        distance = mfcd::tools::parse_double("--distance", v);
        if (!(distance > 0)) throw std::invalid_argument("--distance '" + v + "' is not a positive number");
      } else if (a == "--quiet") quiet = true;
      else if (a == "--preview") preview = value("--preview");
      else if (!a.empty() && a[0] == '-') throw std::invalid_argument("unknown option " + a);
      else if (model.empty()) model = a;
      else throw std::invalid_argument("more than one MODEL given ('" + model + "', '" + a + "')");
    }
    if (model.empty() || camera.empty() || out.empty()) {
      usage(stderr);
      return 2;
    }
    if (obj_id < 0) obj_id = default_obj_id(model);
    if (obj_id < 1 || obj_id > 999999) throw std::invalid_argument("--obj-id must be in 1..999999");
    if (name.empty()) name = std::filesystem::path(model).stem().string();

    MeshLoadOptions mo;
    mo.unit_mm = parse_unit_mm(unit);
    MeshReport report;
    const Mesh mesh = load_mesh(model, mo, &report);
    for (const auto& w : report.warnings) std::fprintf(stderr, "mfc-teach: %s: warning: %s\n", model.c_str(), w.c_str());
    const CameraConfig cam = load_camera_config(camera);

    TeachParams tp;
    tp.sphere_samples = views;
    tp.symmetry = PartSymmetry::parse(symmetry);
    // teach_templates refuses a fold that is not a subgroup of the part's symmetry.
    if (!views_symmetry.empty()) tp.views_symmetry = PartSymmetry::parse(views_symmetry);
    tp.distance_mm = distance;
    tp.threads = threads;
    tp.lighting_turns = lighting_turns;
    tp.lighting_min_turns = lighting_min_turns;
    tp.lighting_tolerance_px = lighting_tolerance;
    const auto t0 = std::chrono::steady_clock::now();
    auto seconds = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
    const bool bar = !quiet;
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
    save_template_database(db, out);
    if (!preview.empty()) write_preview(db, preview);
    size_t lines = 0, points = 0;
    for (const auto& v : db.views) lines += v.lines.lines.size(), points += v.points.size();
    // The edge offset profiles within 10 degrees of the image axes (docs/template-database.md): the
    // views' and the query's differ by a few tenths of a pixel there, which the pose fit corrects.
    std::printf("%s: part %s obj_id %d symmetry %s, views folded by %s: %zu views (K = %d), %.1f lines and %.0f edge points per view, "
                "distance %.1f mm, edge offset near image axes %.2f px (views) / %.2f px (query), lighting turns %d:%d, "
                "turns from the mesh: %s, %.1f s\n",
                out.c_str(), name.c_str(), obj_id, db.symmetry.str().c_str(), db.views_symmetry.str().c_str(), db.views.size(), views,
                double(lines) / db.views.size(), double(points) / db.views.size(), db.distance_mm,
                db.template_edge_offset.mean_near(0, 10), db.query_edge_offset.mean_near(0, 10), lighting_turns,
                lighting_min_turns, describe(db.turns).c_str(), seconds());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "\nmfc-teach: %s\n", e.what());
    return 1;
  }
}
