#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <opencv2/imgproc.hpp>

#include "vision/detect/shape_detector.hpp"

using namespace mfcd::vision;

namespace {
// Outlines of two made-up parts (pixels, around the origin).
const std::vector<cv::Point2d> kTNut{{-40, -30}, {40, -30}, {40, -10},  {15, -10},
                                     {15, 30},   {-15, 30}, {-15, -10}, {-40, -10}};
const std::vector<cv::Point2d> kBracket{{-35, -35}, {35, -35}, {35, -20}, {-20, -20}, {-20, 35}, {-35, 35}};

std::vector<cv::Point> place(const std::vector<cv::Point2d>& shape, cv::Point2d at, double angle, double scale,
                             double aspect = 1) {
  std::vector<cv::Point> out;
  const double c = std::cos(angle), s = std::sin(angle);
  for (const auto& p : shape) {
    const double x = p.x * scale * aspect, y = p.y * scale;
    out.emplace_back(cvRound(at.x + c * x - s * y), cvRound(at.y + s * x + c * y));
  }
  return out;
}

ShapeTemplate makeTemplate(const std::vector<cv::Point2d>& shape, const std::string& name) {
  cv::Mat1b img(120, 120, uchar(0));
  cv::polylines(img, std::vector<std::vector<cv::Point>>{place(shape, {60, 60}, 0, 1)}, true, 255, 1);
  return templateFromEdges(img, name, {});
}

struct Planted {
  cv::Point2d at;
  double angle, scale, aspect;
};

// A grey scene: filled parts on a textured background, clutter lines and sensor noise.
cv::Mat1b scene(std::mt19937& rng, const std::vector<cv::Point2d>& shape, const std::vector<Planted>& parts) {
  cv::Mat1b img(360, 480, uchar(60));
  std::uniform_int_distribution<int> ux(0, 479), uy(0, 359), ug(20, 120);
  for (int i = 0; i < 25; ++i) cv::line(img, {ux(rng), uy(rng)}, {ux(rng), uy(rng)}, ug(rng), 1);
  for (const auto& p : parts)
    cv::fillPoly(img, std::vector<std::vector<cv::Point>>{place(shape, p.at, p.angle, p.scale, p.aspect)}, 200);
  cv::Mat1s noise(img.size());
  cv::randn(noise, 0, 4);
  cv::Mat1s tmp;
  img.convertTo(tmp, CV_16S);
  tmp += noise;
  tmp.convertTo(img, CV_8U);
  return img;
}
}  // namespace

TEST(ShapeDetector, FindsRotatedPartsInClutter) {
  std::mt19937 rng(2);
  DetectorParams p;
  p.threshold = 2.0;
  ShapeDetector det(p);
  det.addTemplate(makeTemplate(kTNut, "tnut"));
  const double step = OrientationChannels(60).step();
  const std::vector<Planted> parts{
      {{110, 100}, 7 * step, 1, 1}, {{330, 110}, 61 * step, 1, 1}, {{220, 260}, 100 * step, 1, 1}};
  const DetectionReport r = det.detect(scene(rng, kTNut, parts));
  ASSERT_GE(r.detections.size(), 3u);
  for (const auto& part : parts) {
    bool found = false;
    for (size_t i = 0; i < 3; ++i) {
      const auto& d = r.detections[i];
      const double dAngle = std::remainder(d.angleDeg * CV_PI / 180 - part.angle, 2 * CV_PI);
      found |= cv::norm(d.position - part.at) <= 2.0 && std::abs(dAngle) <= 1.5 * step;
    }
    EXPECT_TRUE(found) << "part at " << part.at;
  }
  EXPECT_GT(r.stats.skipped, 0u);
}

// Sec. 5.2 setup: scales with ratio 1.2 and aspects with ratio 1.1 recover a stretched copy.
TEST(ShapeDetector, RecoversScaleAndAspect) {
  std::mt19937 rng(3);
  DetectorParams p;
  p.threshold = 2.0;
  p.warps.angleStepChannels = 2;
  p.warps.angleMin = -0.3;
  p.warps.angleMax = 0.3;
  p.warps.scales = WarpGrid::series(1.0, 1.2, 3);
  p.warps.aspects = WarpGrid::series(1.0, 1.1, 3);
  ShapeDetector det(p);
  det.addTemplate(makeTemplate(kBracket, "bracket"));
  const DetectionReport r = det.detect(scene(rng, kBracket, {{{240, 180}, 0, 1.2, 1.1}}));
  ASSERT_FALSE(r.detections.empty());
  const auto& d = r.detections.front();
  EXPECT_NEAR(d.scale, 1.2, 1e-9);
  EXPECT_NEAR(d.aspect, 1.1, 1e-9);
  EXPECT_LE(cv::norm(d.position - cv::Point2d(240, 180)), 2.5);
}

TEST(ShapeDetector, BaselinesAndMajorLineSearchRunTheSameHypotheses) {
  std::mt19937 rng(4);
  const cv::Mat1b img = scene(rng, kTNut, {{{200, 150}, 0.5, 1, 1}});
  DetectorParams p;
  p.threshold = 3.0;
  std::vector<DetectionReport> reports;
  for (MatchMethod m : {MatchMethod::Fdcm, MatchMethod::OrientedChamfer, MatchMethod::Chamfer}) {
    p.method = m;
    ShapeDetector det(p);
    det.addTemplate(makeTemplate(kTNut, "tnut"));
    reports.push_back(det.detect(img));
    ASSERT_FALSE(reports.back().detections.empty()) << toString(m);
    EXPECT_LE(cv::norm(reports.back().detections[0].position - cv::Point2d(200, 150)), 3.0) << toString(m);
  }
  EXPECT_EQ(reports[0].stats.hypotheses, reports[1].stats.hypotheses);
  EXPECT_EQ(reports[0].stats.hypotheses, reports[2].stats.hypotheses);
  p.method = MatchMethod::Fdcm;
  p.strategy = SearchStrategy::MajorLines;
  ShapeDetector lines(p);
  lines.addTemplate(makeTemplate(kTNut, "tnut"));
  const auto r = lines.detect(img);
  ASSERT_FALSE(r.detections.empty());
  EXPECT_LE(cv::norm(r.detections[0].position - cv::Point2d(200, 150)), 3.0);
  EXPECT_LT(r.stats.hypotheses * 50, reports[0].stats.hypotheses);
}

TEST(ShapeDetector, GalleryRetrievalRanksTheRightTemplateFirst) {
  std::mt19937 rng(5);
  DetectorParams p;
  p.warps.angleStepChannels = 3;
  ShapeDetector det(p);
  det.addTemplate(makeTemplate(kBracket, "bracket"));
  det.addTemplate(makeTemplate(kTNut, "tnut"));
  const auto ranked = det.rank(scene(rng, kTNut, {{{240, 180}, 1.0, 1, 1}}));
  ASSERT_EQ(ranked.size(), 2u);
  EXPECT_EQ(ranked[0].name, "tnut");
  EXPECT_LT(ranked[0].cost, ranked[1].cost);
}

TEST(ShapeDetector, BadInputGetsClearErrors) {
  DetectorParams p;
  ShapeDetector det(p);
  EXPECT_THROW(det.detect(cv::Mat1b(10, 10, uchar(0))), std::logic_error) << "no templates";
  det.addTemplate(makeTemplate(kTNut, "tnut"));
  EXPECT_THROW(det.detect(cv::Mat()), std::invalid_argument);
  EXPECT_THROW(templateFromEdges(cv::Mat1b(50, 50, uchar(0)), "blank", {}), std::invalid_argument);
  EXPECT_THROW(matchMethodFromString("sift"), std::invalid_argument);
  EXPECT_THROW(loadTemplate("/nonexistent.png", {}, 50, 150), std::runtime_error);
  p.threshold = -1;
  EXPECT_THROW(ShapeDetector{p}, std::invalid_argument);
  p = {};
  p.method = MatchMethod::Chamfer;
  p.strategy = SearchStrategy::MajorLines;
  EXPECT_THROW(ShapeDetector{p}, std::invalid_argument);
  // No edges in the query: no detections, no error.
  EXPECT_TRUE(det.detect(cv::Mat1b(100, 100, uchar(0))).detections.empty());
}
