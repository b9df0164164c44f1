// mfc-match: the FDCM 2-D shape detector on image files.
//   mfc-match --template T.png|T.lines [--template ...] --query Q.png [options]
// Prints the detections as JSON on stdout; --overlay writes a PNG with them drawn. `--help` for
// the options; usage errors exit 2, failures 1.
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "tools/common/cli.hpp"
#include "vision/detect/shape_detector.hpp"

using namespace mfcd::vision;

namespace {

// The detector's options (DetectorParams) and the command's own, as the usage lists them.
struct Options {
  std::vector<std::string> templates;
  std::string query, jsonOut, overlayOut, saveLines, mode = "detect";
  DetectorParams p;
  int scales = 1, aspects = 1;
  double scaleRatio = 1.2, aspectRatio = 1.1;
};

// A number option; a value that is not one is refused naming the option ("--threshold expects a
// number, got 'abc'").
double number(const std::string& opt, const std::string& v) {
  char* end = nullptr;
  const double x = std::strtod(v.c_str(), &end);
  if (v.empty() || *end) throw mfcd::tools::UsageError(opt + " expects a number, got '" + v + "'");
  return x;
}

template <class T>
CLI::Option* addNumber(CLI::App& app, const std::string& name, T& into, const std::string& help) {
  return mfcd::tools::add_converted(
      app, name, into, [](const std::string& o, const std::string& v) { return static_cast<T>(number(o, v)); }, help);
}

void addOptions(CLI::App& app, Options& o) {
  DetectorParams& p = o.p;
  app.add_option("--template", o.templates,
                 "edge image (PNG; non-binary images go through Canny) or line file\n"
                 "(*.lines); repeat for more templates")
      ->type_name("FILE")
      ->allow_extra_args(false)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  app.add_option("--query", o.query, "query image (binary edge map, or grey/colour -> Canny)")->type_name("IMAGE");
  app.add_option("--json", o.jsonOut, "also write the JSON result to FILE (it always goes to stdout)")
      ->type_name("FILE");
  app.add_option("--overlay", o.overlayOut, "write a PNG of the query with the detections drawn")->type_name("FILE");
  app.add_option("--save-lines", o.saveLines, "write the first template's fitted lines as a line file")
      ->type_name("FILE");
  app.add_option("--mode", o.mode,
                 "detect: every detection under the threshold (default);\n"
                 "rank: best placement of each template, cheapest first (gallery)")
      ->type_name("detect|rank");
  mfcd::tools::add_converted(
      app, "--method", p.method, [](const std::string&, const std::string& v) { return matchMethodFromString(v); },
      "matching cost (default fdcm)")
      ->type_name("fdcm|ocm|cm");
  mfcd::tools::add_converted(
      app, "--search", p.strategy,
      [](const std::string&, const std::string& s) {
        if (s == "exhaustive") return SearchStrategy::Exhaustive;
        if (s == "lines") return SearchStrategy::MajorLines;
        throw mfcd::tools::UsageError("--search expects exhaustive or lines, got '" + s + "'");
      },
      "exhaustive bounded search (default) or 1-D search along major lines")
      ->type_name("exhaustive|lines");
  addNumber(app, "--threshold", p.threshold, "detection threshold, mean cost in px (default 3)")->type_name("PX");
  addNumber(app, "--max-detections", p.maxDetections, "after non-maximum suppression (default 20)")->type_name("N");
  addNumber(app, "--nms-iou", p.nmsMaxIoU, "max overlap between kept detections (default 0.3)")->type_name("X");
  addNumber(app, "--rotation-step", p.warps.angleStepChannels,
            "in-plane rotation step in channels of 180/q degrees (default 1)")
      ->type_name("CH");
  mfcd::tools::add_converted(
      app, "--angle-min", p.warps.angleMin,
      [](const std::string& opt, const std::string& v) { return number(opt, v) * CV_PI / 180; },
      "rotation range start (default 0)")
      ->type_name("DEG");
  mfcd::tools::add_converted(
      app, "--angle-max", p.warps.angleMax,
      [](const std::string& opt, const std::string& v) { return number(opt, v) * CV_PI / 180; },
      "rotation range end (default 360)")
      ->type_name("DEG");
  addNumber(app, "--scales", o.scales, "N scales (default 1)")->type_name("N");
  addNumber(app, "--scale-ratio", o.scaleRatio, "ratio between neighbouring scales (default 1.2)")->type_name("R");
  addNumber(app, "--aspects", o.aspects, "N aspects (default 1)")->type_name("N");
  addNumber(app, "--aspect-ratio", o.aspectRatio, "ratio between neighbouring aspects (default 1.1)")->type_name("R");
  // q is the line fitter's and DT3's: both are set.
  mfcd::tools::add_converted(
      app, "--q", p.dt3.q,
      [&p](const std::string& opt, const std::string& v) { return p.lines.q = static_cast<int>(number(opt, v)); },
      "DT3 orientation channels (default 60)")
      ->type_name("N");
  addNumber(app, "--lambda", p.dt3.lambda, "DT3 orientation cost, px per channel (default 0.5)")->type_name("X");
  addNumber(app, "--max-cost", p.dt3.maxCost, "DT3 truncation (default 30 px)")->type_name("PX");
  app.add_option_function<std::vector<std::string>>(
         "--canny",
         [&p](const std::vector<std::string>& v) {
           p.cannyLow = number("--canny", v[0]);
           p.cannyHigh = number("--canny", v[1]);
         },
         "Canny thresholds for grey images (default 50 150)")
      ->expected(2)
      ->type_name("LOW HIGH");
  app.add_flag_callback(
      "--no-bounds", [&p] { p.hypothesisBound = p.spatialBound = false; },
      "disable both search bounds (exhaustive reference)");
  addNumber(app, "--threads", p.threads, "worker threads (default: all cores)")->type_name("N");
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Finds the templates in the query image with Fast Directional Chamfer Matching and prints the\n"
      "detections as JSON on stdout.",
      "mfc-match"};
  mfcd::tools::init_app(app);
  Options o;
  addOptions(app, o);
  if (const auto code = mfcd::tools::parse(app, argc, argv)) return *code;
  if (o.templates.empty()) return mfcd::tools::usage_error(app, "at least one --template is required");
  if (o.query.empty()) return mfcd::tools::usage_error(app, "--query is required");
  if (o.mode != "detect" && o.mode != "rank") return mfcd::tools::usage_error(app, "--mode expects detect or rank");
  DetectorParams& p = o.p;

  try {
    p.warps.scales = WarpGrid::series(1.0, o.scaleRatio, o.scales);
    p.warps.aspects = WarpGrid::series(1.0, o.aspectRatio, o.aspects);
    ShapeDetector det(p);
    for (const auto& t : o.templates) det.addTemplate(loadTemplate(t, p.lines, p.cannyLow, p.cannyHigh));
    if (!o.saveLines.empty()) writeLineFile(o.saveLines, det.templates().front().lines);
    const cv::Mat img = cv::imread(o.query, cv::IMREAD_UNCHANGED);
    if (img.empty()) throw std::runtime_error(o.query + ": not a readable image");

    DetectionReport report;
    if (o.mode == "rank")
      report.detections = det.rank(img);
    else
      report = det.detect(img);

    nlohmann::json out;
    out["version"] = mfcd::version();
    out["commit"] = mfcd::git_commit();
    out["query"] = o.query;
    out["method"] = toString(p.method);
    out["search"] = p.strategy == SearchStrategy::Exhaustive ? "exhaustive" : "lines";
    out["mode"] = o.mode;
    out["threshold_px"] = p.threshold;
    nlohmann::json dets = nlohmann::json::array();
    for (const auto& d : report.detections) {
      dets.push_back({{"template", d.name},
                      {"x", d.position.x},
                      {"y", d.position.y},
                      {"angle_deg", d.angleDeg},
                      {"scale", d.scale},
                      {"aspect", d.aspect},
                      {"cost_px", d.cost},
                      {"box", {d.box.x, d.box.y, d.box.width, d.box.height}}});
    }
    out["detections"] = dets;
    if (o.mode == "detect") {
      out["stats"] = {{"query_edge_pixels", report.queryEdgePixels},
                      {"query_lines", report.queryLines},
                      {"hypotheses", report.stats.hypotheses},
                      {"evaluated", report.stats.evaluated},
                      {"skipped_spatial", report.stats.skipped},
                      {"segments_read", report.stats.segments},
                      {"truncated", report.truncated},
                      {"ms",
                       {{"edges", report.msEdges},
                        {"lines", report.msLines},
                        {"distance", report.msDistance},
                        {"search", report.msSearch},
                        {"total", report.msTotal}}}};
    }
    const std::string text = out.dump(2);
    std::cout << text << "\n";
    if (!o.jsonOut.empty()) {
      std::ofstream f(o.jsonOut);
      f << text << "\n";
      if (!f) throw std::runtime_error(o.jsonOut + ": cannot write");
    }
    if (!o.overlayOut.empty() && !cv::imwrite(o.overlayOut, drawDetections(img, report.detections)))
      throw std::runtime_error(o.overlayOut + ": cannot write overlay PNG");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mfc-match: %s\n", e.what());
    return 1;
  }
  return 0;
}
