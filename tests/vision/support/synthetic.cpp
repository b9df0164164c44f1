#include "tests/vision/support/synthetic.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <opencv2/imgproc.hpp>

namespace mfcd::vision::testing {

namespace {
void drawSegment(cv::Mat1b& map, cv::Point2d a, cv::Point2d b, int channel) {
  cv::LineIterator it(map, cv::Point(cvRound(a.x), cvRound(a.y)), cv::Point(cvRound(b.x), cvRound(b.y)), 8);
  for (int i = 0; i < it.count; ++i, ++it) map(it.pos()) = static_cast<uchar>(channel);
}
}  // namespace

cv::Mat1b randomChannelMap(std::mt19937& rng, cv::Size size, int q, int segments, int noise, bool oriented) {
  cv::Mat1b map(size, kNoChannel);
  const OrientationChannels ch(q, oriented);
  std::uniform_real_distribution<double> ux(0, size.width - 1), uy(0, size.height - 1), len(3, 40);
  std::uniform_int_distribution<int> uc(0, q - 1);
  for (int i = 0; i < segments; ++i) {
    const int c = uc(rng);
    const cv::Point2d a(ux(rng), uy(rng));
    const double l = len(rng), phi = ch.angleOf(c);
    drawSegment(map, a, a + cv::Point2d(std::cos(phi), std::sin(phi)) * l, c);
  }
  for (int i = 0; i < noise; ++i) map(cvRound(uy(rng)), cvRound(ux(rng))) = static_cast<uchar>(uc(rng));
  return map;
}

LineSet randomLineSet(std::mt19937& rng, int q, int count, double minLen, double maxLen, double extent, bool oriented) {
  LineSet set;
  set.q = q;
  set.oriented = oriented;
  set.size = cv::Size(static_cast<int>(2 * extent + 1), static_cast<int>(2 * extent + 1));
  set.origin = cv::Point2f(0, 0);
  const OrientationChannels ch(q, oriented);
  std::uniform_real_distribution<double> u(-extent, extent), len(minLen, maxLen);
  std::uniform_int_distribution<int> uc(0, q - 1);
  while (static_cast<int>(set.lines.size()) < count) {
    const int c = uc(rng);
    const double phi = ch.angleOf(c), l = len(rng);
    const cv::Point2d a(u(rng), u(rng));
    const cv::Point2d b = a + cv::Point2d(std::cos(phi), std::sin(phi)) * l;
    if (std::abs(b.x) > extent || std::abs(b.y) > extent) continue;
    LineSegment s;
    s.a = cv::Point2f(a);
    s.b = cv::Point2f(b);
    s.channel = c;
    s.support = static_cast<int>(l);
    set.lines.push_back(s);
  }
  sortLongestFirst(set.lines);
  return set;
}

void drawLineSet(cv::Mat1b& channelMap, const LineSet& set, cv::Point2d at) {
  for (const auto& l : set.lines)
    drawSegment(channelMap, cv::Point2d(l.a) - cv::Point2d(set.origin) + at,
                cv::Point2d(l.b) - cv::Point2d(set.origin) + at, l.channel);
}

double pointToSegment(cv::Point2d p, cv::Point2d a, cv::Point2d b) {
  const cv::Point2d d = b - a;
  const double t = std::clamp((p - a).dot(d) / d.dot(d), 0.0, 1.0);
  return cv::norm(p - (a + d * t));
}

std::vector<std::array<int, 3>> labelledPixels(const cv::Mat1b& channelMap) {
  std::vector<std::array<int, 3>> v;
  for (int y = 0; y < channelMap.rows; ++y)
    for (int x = 0; x < channelMap.cols; ++x)
      if (channelMap(y, x) != kNoChannel) v.push_back({x, y, channelMap(y, x)});
  return v;
}

std::vector<cv::Point2d> randomPolygon(std::mt19937& rng, cv::Point2d centre, double radius, int count) {
  std::uniform_real_distribution<double> ua(0, 2 * std::numbers::pi), ur(0.6, 1.0);
  // Rejection sampling: every corner must turn by 30..150 degrees and every edge be at least
  // 40 px long, otherwise neighbouring edges blur into each other for any fitter.
  while (true) {
    std::vector<double> angles(count);
    for (auto& a : angles) a = ua(rng);
    std::sort(angles.begin(), angles.end());
    std::vector<cv::Point2d> pts;
    for (double a : angles) {
      const double r = radius * ur(rng);
      pts.emplace_back(std::round(centre.x + r * std::cos(a)), std::round(centre.y + r * std::sin(a)));
    }
    bool ok = true;
    for (int i = 0; i < count && ok; ++i) {
      const cv::Point2d a = pts[i], b = pts[(i + 1) % count], c = pts[(i + 2) % count];
      const cv::Point2d u = b - a, v = c - b;
      if (cv::norm(u) < 40) ok = false;
      const double turn = std::abs(std::atan2(u.x * v.y - u.y * v.x, u.dot(v)));
      if (turn < 30 * std::numbers::pi / 180 || turn > 150 * std::numbers::pi / 180) ok = false;
    }
    if (ok) return pts;
  }
}

}  // namespace mfcd::vision::testing
