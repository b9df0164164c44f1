// mfc-match: the FDCM 2-D shape detector on image files.
//   mfc-match --template T.png|T.lines [--template ...] --query Q.png [options]
// Prints the detections as JSON on stdout; --overlay writes a PNG with them drawn.
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "vision/detect/shape_detector.hpp"

using namespace mfcd::vision;

namespace {

const char* kUsage = R"(usage: mfc-match --template FILE [--template FILE ...] --query IMAGE [options]

Finds the templates in the query image with Fast Directional Chamfer Matching.
Templates: edge images (PNG; non-binary images go through Canny) or line files (*.lines).

  --query IMAGE          query image (binary edge map, or grey/colour -> Canny)
  --json FILE            also write the JSON result to FILE (it always goes to stdout)
  --overlay FILE         write a PNG of the query with the detections drawn
  --save-lines FILE      write the first template's fitted lines as a line file
  --mode detect|rank     detect: every detection under the threshold (default);
                         rank: best placement of each template, cheapest first (gallery)
  --method fdcm|ocm|cm   matching cost (default fdcm)
  --search exhaustive|lines   exhaustive bounded search (default) or 1-D search along major lines
  --threshold PX         detection threshold, mean cost in px (default 3)
  --max-detections N     after non-maximum suppression (default 20)
  --nms-iou X            max overlap between kept detections (default 0.3)
  --rotation-step CH     in-plane rotation step in channels of 180/q degrees (default 1)
  --angle-min DEG --angle-max DEG   rotation range (default 0..360)
  --scales N --scale-ratio R        N scales, ratio R between neighbours (default 1, 1.2)
  --aspects N --aspect-ratio R      N aspects, ratio R (default 1, 1.1)
  --q N --lambda X --max-cost PX    DT3 parameters (default 60, 0.5 px/channel, 30 px)
  --canny LOW HIGH       Canny thresholds for grey images (default 50 150)
  --no-bounds            disable both search bounds (exhaustive reference)
  --threads N            worker threads (default: all cores)
)";

[[noreturn]] void usageError(const std::string& msg) {
  std::fprintf(stderr, "mfc-match: %s\n\n%s", msg.c_str(), kUsage);
  std::exit(2);
}

double number(const std::string& opt, const char* v) {
  char* end = nullptr;
  const double x = std::strtod(v, &end);
  if (!v[0] || *end) usageError(opt + " expects a number, got '" + v + "'");
  return x;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> templates;
  std::string query, jsonOut, overlayOut, saveLines, mode = "detect";
  DetectorParams p;
  int scales = 1, aspects = 1;
  double scaleRatio = 1.2, aspectRatio = 1.1;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> const char* {
      if (i + 1 >= argc) usageError(a + " needs a value");
      return argv[++i];
    };
    if (a == "--help" || a == "-h") {
      std::fputs(kUsage, stdout);
      return 0;
    } else if (a == "--template") templates.emplace_back(value());
    else if (a == "--query") query = value();
    else if (a == "--json") jsonOut = value();
    else if (a == "--overlay") overlayOut = value();
    else if (a == "--save-lines") saveLines = value();
    else if (a == "--mode") mode = value();
    else if (a == "--method") {
      try {
        p.method = matchMethodFromString(value());
      } catch (const std::exception& e) {
        usageError(e.what());
      }
    } else if (a == "--search") {
      const std::string s = value();
      if (s == "exhaustive") p.strategy = SearchStrategy::Exhaustive;
      else if (s == "lines") p.strategy = SearchStrategy::MajorLines;
      else usageError("--search expects exhaustive or lines, got '" + s + "'");
    } else if (a == "--threshold") p.threshold = number(a, value());
    else if (a == "--max-detections") p.maxDetections = static_cast<size_t>(number(a, value()));
    else if (a == "--nms-iou") p.nmsMaxIoU = number(a, value());
    else if (a == "--rotation-step") p.warps.angleStepChannels = static_cast<int>(number(a, value()));
    else if (a == "--angle-min") p.warps.angleMin = number(a, value()) * CV_PI / 180;
    else if (a == "--angle-max") p.warps.angleMax = number(a, value()) * CV_PI / 180;
    else if (a == "--scales") scales = static_cast<int>(number(a, value()));
    else if (a == "--scale-ratio") scaleRatio = number(a, value());
    else if (a == "--aspects") aspects = static_cast<int>(number(a, value()));
    else if (a == "--aspect-ratio") aspectRatio = number(a, value());
    else if (a == "--q") p.lines.q = p.dt3.q = static_cast<int>(number(a, value()));
    else if (a == "--lambda") p.dt3.lambda = number(a, value());
    else if (a == "--max-cost") p.dt3.maxCost = number(a, value());
    else if (a == "--canny") {
      p.cannyLow = number(a, value());
      p.cannyHigh = number(a, value());
    } else if (a == "--no-bounds") p.hypothesisBound = p.spatialBound = false;
    else if (a == "--threads") p.threads = static_cast<int>(number(a, value()));
    else usageError("unknown option '" + a + "'");
  }
  if (templates.empty()) usageError("at least one --template is required");
  if (query.empty()) usageError("--query is required");
  if (mode != "detect" && mode != "rank") usageError("--mode expects detect or rank");

  try {
    p.warps.scales = WarpGrid::series(1.0, scaleRatio, scales);
    p.warps.aspects = WarpGrid::series(1.0, aspectRatio, aspects);
    ShapeDetector det(p);
    for (const auto& t : templates) det.addTemplate(loadTemplate(t, p.lines, p.cannyLow, p.cannyHigh));
    if (!saveLines.empty()) writeLineFile(saveLines, det.templates().front().lines);
    const cv::Mat img = cv::imread(query, cv::IMREAD_UNCHANGED);
    if (img.empty()) throw std::runtime_error(query + ": not a readable image");

    DetectionReport report;
    if (mode == "rank") report.detections = det.rank(img);
    else report = det.detect(img);

    nlohmann::json out;
    out["query"] = query;
    out["method"] = toString(p.method);
    out["search"] = p.strategy == SearchStrategy::Exhaustive ? "exhaustive" : "lines";
    out["mode"] = mode;
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
    if (mode == "detect") {
      out["stats"] = {{"query_edge_pixels", report.queryEdgePixels},
                      {"query_lines", report.queryLines},
                      {"hypotheses", report.stats.hypotheses},
                      {"evaluated", report.stats.evaluated},
                      {"skipped_spatial", report.stats.skipped},
                      {"segments_read", report.stats.segments},
                      {"truncated", report.truncated},
                      {"ms", {{"edges", report.msEdges}, {"lines", report.msLines}, {"distance", report.msDistance},
                              {"search", report.msSearch}, {"total", report.msTotal}}}};
    }
    const std::string text = out.dump(2);
    std::cout << text << "\n";
    if (!jsonOut.empty()) {
      std::ofstream f(jsonOut);
      f << text << "\n";
      if (!f) throw std::runtime_error(jsonOut + ": cannot write");
    }
    if (!overlayOut.empty() && !cv::imwrite(overlayOut, drawDetections(img, report.detections)))
      throw std::runtime_error(overlayOut + ": cannot write overlay PNG");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mfc-match: %s\n", e.what());
    return 1;
  }
  return 0;
}
