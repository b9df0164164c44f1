#include "vision/detect/shape_detector.hpp"

#include <chrono>
#include <cmath>
#include <stdexcept>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "vision/dt3/directional_distance_transform.hpp"
#include "vision/idt3/integral_distance_transform.hpp"
#include "vision/search/matchers.hpp"
#include "vision/search/nms.hpp"

namespace mfcd::vision {

namespace {
using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }
}  // namespace

const char* toString(MatchMethod m) {
  switch (m) {
    case MatchMethod::Fdcm:
      return "fdcm";
    case MatchMethod::OrientedChamfer:
      return "ocm";
    case MatchMethod::Chamfer:
      return "cm";
  }
  return "?";
}

MatchMethod matchMethodFromString(const std::string& s) {
  if (s == "fdcm") return MatchMethod::Fdcm;
  if (s == "ocm") return MatchMethod::OrientedChamfer;
  if (s == "cm") return MatchMethod::Chamfer;
  throw std::invalid_argument("unknown matching method '" + s + "' (expected fdcm, ocm or cm)");
}

void DetectorParams::validate() const {
  lines.validate();
  dt3.validate();
  if (lines.q != dt3.q) throw std::invalid_argument("detector: lines.q and dt3.q differ");
  if (!(threshold > 0)) throw std::invalid_argument("detector: threshold must be > 0 px");
  if (!(nmsMaxIoU >= 0 && nmsMaxIoU <= 1)) throw std::invalid_argument("detector: nmsMaxIoU must be in [0, 1]");
  if (maxDetections == 0) throw std::invalid_argument("detector: maxDetections must be >= 1");
  if (!(spatialReach >= 0)) throw std::invalid_argument("detector: spatialReach must be >= 0");
  if (strategy == SearchStrategy::MajorLines && method != MatchMethod::Fdcm)
    throw std::invalid_argument("detector: the major-lines search is implemented for FDCM only");
  (void)warps.warps(dt3.q);  // validates the grid
}

cv::Mat1b edgesOf(const cv::Mat& image, double cannyLow, double cannyHigh) {
  if (image.empty()) throw std::invalid_argument("empty image");
  cv::Mat grey;
  if (image.channels() == 3)
    cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  else if (image.channels() == 4)
    cv::cvtColor(image, grey, cv::COLOR_BGRA2GRAY);
  else
    grey = image;
  if (grey.depth() != CV_8U) {
    double lo, hi;
    cv::minMaxLoc(grey, &lo, &hi);
    grey.convertTo(grey, CV_8U, hi > lo ? 255.0 / (hi - lo) : 1.0, hi > lo ? -lo * 255.0 / (hi - lo) : 0);
  }
  double lo, hi;
  cv::minMaxLoc(grey, &lo, &hi);
  const int nonzero = cv::countNonZero(grey);
  const int atHi = cv::countNonZero(grey == hi);
  if (lo == 0 && nonzero == atHi) return cv::Mat1b(grey != 0);  // already a binary edge map
  cv::Mat1b edges;
  cv::Canny(grey, edges, cannyLow, cannyHigh, 3, true);
  return edges;
}

ShapeTemplate templateFromEdges(const cv::Mat1b& edges, const std::string& name, const LineFitParams& params) {
  if (edges.empty()) throw std::invalid_argument("template '" + name + "': empty edge image");
  const LineFitResult fit = fitLines(edges, params);
  if (fit.set.lines.empty())
    throw std::invalid_argument("template '" + name + "': no line segments found (" +
                                std::to_string(fit.inputEdgePixels) + " edge pixels)");
  ShapeTemplate t;
  t.name = name;
  t.lines = fit.set;
  cv::Rect2f box;
  bool first = true;
  for (const auto& l : t.lines.lines) {
    const cv::Rect2f r(cv::Point2f(std::min(l.a.x, l.b.x), std::min(l.a.y, l.b.y)),
                       cv::Point2f(std::max(l.a.x, l.b.x), std::max(l.a.y, l.b.y)));
    box = first ? r : (box | r);
    first = false;
  }
  t.lines.origin = (box.tl() + box.br()) * 0.5f;
  return t;
}

ShapeTemplate loadTemplate(const std::filesystem::path& path, const LineFitParams& params, double cannyLow,
                           double cannyHigh) {
  if (!std::filesystem::exists(path)) throw std::runtime_error(path.string() + ": no such file");
  if (path.extension() == ".lines") {
    ShapeTemplate t;
    t.name = path.stem().string();
    // Canny edges (the detector's query) have no polarity: an oriented file is matched without it.
    t.lines = withoutPolarity(readLineFile(path));
    if (t.lines.q != params.q)
      throw std::runtime_error(path.string() + ": line file has q = " + std::to_string(t.lines.q) +
                               " but the detector uses q = " + std::to_string(params.q));
    return t;
  }
  const cv::Mat img = cv::imread(path.string(), cv::IMREAD_UNCHANGED);
  if (img.empty()) throw std::runtime_error(path.string() + ": not a readable image");
  try {
    return templateFromEdges(edgesOf(img, cannyLow, cannyHigh), path.stem().string(), params);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(path.string() + ": " + e.what());
  }
}

ShapeDetector::ShapeDetector(DetectorParams params) : params_(std::move(params)) { params_.validate(); }

void ShapeDetector::addTemplate(ShapeTemplate t) {
  if (t.lines.q != params_.dt3.q)
    throw std::invalid_argument("template '" + t.name + "' has q = " + std::to_string(t.lines.q) +
                                ", detector q = " + std::to_string(params_.dt3.q));
  if (t.lines.oriented) throw std::invalid_argument("template '" + t.name + "' has oriented lines (withoutPolarity)");
  if (t.lines.lines.empty()) throw std::invalid_argument("template '" + t.name + "' has no lines");
  templates_.push_back(std::move(t));
}

DetectionReport ShapeDetector::detect(const cv::Mat& image) const { return run(image, SearchMode::Detect, -1); }

std::vector<Detection> ShapeDetector::rank(const cv::Mat& image) const {
  std::vector<Detection> out;
  for (int i = 0; i < static_cast<int>(templates_.size()); ++i) {
    DetectionReport r = run(image, SearchMode::Best, i);
    if (!r.detections.empty()) out.push_back(r.detections.front());
  }
  std::sort(out.begin(), out.end(), [](const Detection& a, const Detection& b) { return a.cost < b.cost; });
  return out;
}

DetectionReport ShapeDetector::run(const cv::Mat& image, SearchMode mode, int onlyTemplate) const {
  if (templates_.empty()) throw std::logic_error("detector: no templates");
  DetectionReport report;
  const auto t0 = Clock::now();
  auto t = Clock::now();
  const cv::Mat1b edges = edgesOf(image, params_.cannyLow, params_.cannyHigh);
  report.msEdges = msSince(t);
  t = Clock::now();
  const LineFitResult fit = fitLines(edges, params_.lines);
  report.msLines = msSince(t);
  report.queryEdgePixels = fit.inputEdgePixels;
  report.queryLines = static_cast<int>(fit.set.lines.size());

  std::vector<OrientedTemplate> oriented;
  const auto warps = params_.warps.warps(params_.dt3.q);
  for (int i = 0; i < static_cast<int>(templates_.size()); ++i) {
    if (onlyTemplate >= 0 && i != onlyTemplate) continue;
    for (const Warp& w : warps) oriented.push_back(orientTemplate(templates_[i].lines, i, w));
  }

  SearchParams sp;
  sp.mode = mode;
  sp.threshold = mode == SearchMode::Detect ? params_.threshold : std::numeric_limits<double>::infinity();
  sp.hypothesisBound = params_.hypothesisBound;
  sp.spatialBound = params_.spatialBound;
  sp.spatialReach = params_.spatialReach;
  sp.maxCandidates = params_.maxCandidates;
  sp.threads = params_.threads;
  SearchResult result;
  t = Clock::now();
  if (params_.method == MatchMethod::Fdcm) {
    DirectionalDistanceTransform dt3;
    dt3.compute(fit.channelMap, params_.dt3);
    IntegralDistanceTransform idt;
    idt.compute(dt3);
    report.msDistance = msSince(t);
    t = Clock::now();
    const FdcmMatcher m(idt);
    if (params_.strategy == SearchStrategy::MajorLines) {
      LineSearchParams lp;
      lp.templateLines = params_.templateLines;
      lp.queryLines = params_.queryLines;
      lp.mode = mode;
      lp.threshold = sp.threshold;
      lp.hypothesisBound = params_.hypothesisBound;
      lp.maxCandidates = params_.maxCandidates;
      result = lineSearch(m, oriented, fit.set.lines, lp);
    } else {
      result = exhaustiveSearch(m, oriented, sp);
    }
  } else {
    ChamferCosts costs;
    costs.compute(fit.channelMap, params_.dt3);
    report.msDistance = msSince(t);
    t = Clock::now();
    const ChamferMatcher m(costs, params_.method == MatchMethod::Chamfer ? ChamferMatcher::Kind::Chamfer
                                                                         : ChamferMatcher::Kind::OrientedChamfer);
    result = exhaustiveSearch(m, oriented, sp);
  }
  report.msSearch = msSince(t);
  report.stats = result.stats;
  report.truncated = result.truncated;

  const auto kept = nonMaximumSuppression(result.candidates, oriented, params_.nmsMaxIoU,
                                          mode == SearchMode::Detect ? params_.maxDetections : 1);
  for (const auto& c : kept) {
    const OrientedTemplate& ot = oriented[c.oriented];
    Detection d;
    d.templateIndex = ot.templateIndex;
    d.name = templates_[ot.templateIndex].name;
    d.position = cv::Point2d(c.tx, c.ty);
    d.angleDeg = ot.warp.angle * 180.0 / CV_PI;
    d.scale = ot.warp.scale;
    d.aspect = ot.warp.aspect;
    d.cost = c.cost();
    d.box = placedBox(ot, c);
    for (auto l : ot.lines) {
      l.a += cv::Point2f(static_cast<float>(c.tx), static_cast<float>(c.ty));
      l.b += cv::Point2f(static_cast<float>(c.tx), static_cast<float>(c.ty));
      d.lines.push_back(l);
    }
    report.detections.push_back(std::move(d));
  }
  report.msTotal = msSince(t0);
  return report;
}

cv::Mat3b drawDetections(const cv::Mat& image, const std::vector<Detection>& detections) {
  cv::Mat3b out;
  if (image.channels() == 3)
    out = image.clone();
  else {
    cv::Mat grey;
    if (image.depth() != CV_8U)
      image.convertTo(grey, CV_8U);
    else
      grey = image;
    cv::cvtColor(grey, out, cv::COLOR_GRAY2BGR);
  }
  out = out * 0.6;
  static const cv::Scalar colours[] = {{0, 255, 0}, {0, 200, 255}, {255, 120, 0}, {255, 0, 255}, {0, 0, 255}};
  for (size_t i = 0; i < detections.size(); ++i) {
    const auto& d = detections[i];
    const cv::Scalar col = colours[i % 5];
    for (const auto& l : d.lines) cv::line(out, l.a, l.b, col, 2, cv::LINE_AA);
    cv::circle(out, d.position, 3, col, -1);
    char label[96];
    std::snprintf(label, sizeof label, "#%zu %s %.2fpx", i + 1, d.name.c_str(), d.cost);
    cv::putText(out, label, cv::Point(static_cast<int>(d.box.x), std::max(12, static_cast<int>(d.box.y) - 4)),
                cv::FONT_HERSHEY_SIMPLEX, 0.45, col, 1, cv::LINE_AA);
  }
  return out;
}

}  // namespace mfcd::vision
