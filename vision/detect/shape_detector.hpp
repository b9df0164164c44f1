#pragma once
// 2-D shape detection with FDCM (paper Sec. 5.2-5.3): templates are line sets (from a template
// edge image or a line file); a query image becomes edges -> lines -> DT3 -> IDT3; the search
// runs over in-plane rotation, scale, aspect and translation; non-maximum suppression keeps the
// cheapest of overlapping detections. The same detector runs the CM and OCM baselines.
#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "vision/lines/line_fitter.hpp"
#include "vision/search/exhaustive_search.hpp"
#include "vision/search/line_search.hpp"
#include "vision/search/oriented_template.hpp"

namespace mfcd::vision {

struct ShapeTemplate {
  std::string name;
  LineSet lines;  // origin = the reference point detections report
};

// Edge image (nonzero = edge) -> template; origin at the centre of the edges' bounding box.
ShapeTemplate templateFromEdges(const cv::Mat1b& edges, const std::string& name, const LineFitParams& params);
// Image file: a binary edge image is used as is, anything else goes through Canny first.
// Line files (*.lines) are read directly. Errors name the file and the reason.
ShapeTemplate loadTemplate(const std::filesystem::path& path, const LineFitParams& params, double cannyLow,
                           double cannyHigh);

enum class MatchMethod { Fdcm, OrientedChamfer, Chamfer };
enum class SearchStrategy { Exhaustive, MajorLines };
const char* toString(MatchMethod m);
MatchMethod matchMethodFromString(const std::string& s);  // "fdcm", "ocm", "cm"

struct DetectorParams {
  LineFitParams lines;
  Dt3Params dt3;
  WarpGrid warps;
  MatchMethod method = MatchMethod::Fdcm;
  SearchStrategy strategy = SearchStrategy::Exhaustive;
  double threshold = 3.0;  // px: detections have mean DCM cost <= threshold
  bool hypothesisBound = true;
  bool spatialBound = true;
  double spatialReach = 4.0;
  double nmsMaxIoU = 0.3;
  size_t maxDetections = 20;
  size_t maxCandidates = 200000;
  int templateLines = 5, queryLines = 40;  // MajorLines strategy
  double cannyLow = 50, cannyHigh = 150;   // grey query images
  int threads = 0;

  void validate() const;  // throws std::invalid_argument naming the field
};

struct Detection {
  int templateIndex = 0;
  std::string name;
  cv::Point2d position;  // where the template origin lands in the query
  double angleDeg = 0, scale = 1, aspect = 1;
  double cost = 0;  // mean DCM (or CM/OCM) cost, px
  cv::Rect2d box;
  std::vector<LineSegment> lines;  // template lines placed in the query
};

struct DetectionReport {
  std::vector<Detection> detections;  // best first
  SearchStats stats;
  bool truncated = false;
  int queryEdgePixels = 0, queryLines = 0;
  double msEdges = 0, msLines = 0, msDistance = 0, msSearch = 0, msTotal = 0;
};

// Binary images (only 0 and one other value) are edge maps; others go through Canny.
cv::Mat1b edgesOf(const cv::Mat& image, double cannyLow, double cannyHigh);

class ShapeDetector {
 public:
  explicit ShapeDetector(DetectorParams params);
  void addTemplate(ShapeTemplate t);
  const std::vector<ShapeTemplate>& templates() const { return templates_; }
  const DetectorParams& params() const { return params_; }

  DetectionReport detect(const cv::Mat& image) const;
  // Gallery retrieval (Sec. 5.3): the best placement of every template, cheapest first.
  std::vector<Detection> rank(const cv::Mat& image) const;

 private:
  DetectionReport run(const cv::Mat& image, SearchMode mode, int onlyTemplate) const;
  DetectorParams params_;
  std::vector<ShapeTemplate> templates_;
};

cv::Mat3b drawDetections(const cv::Mat& image, const std::vector<Detection>& detections);

}  // namespace mfcd::vision
