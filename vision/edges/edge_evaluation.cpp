#include "vision/edges/edge_evaluation.hpp"

#include <opencv2/imgproc.hpp>

#include <cmath>

namespace mfcd::vision {

cv::Mat1b depth_discontinuities(const cv::Mat1f& depth, float min_jump_mm) {
  cv::Mat1b out(depth.size(), 0);
  for (int y = 0; y < depth.rows; ++y)
    for (int x = 0; x < depth.cols; ++x) {
      const float z = depth(y, x);
      if (z <= 0) continue;
      const int nb[4][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
      for (const auto& o : nb) {
        const int u = x + o[0], v = y + o[1];
        if (u < 0 || v < 0 || u >= depth.cols || v >= depth.rows) continue;
        const float q = depth(v, u);
        if (q <= 0 || q - z > min_jump_mm) {
          out(y, x) = 255;
          break;
        }
      }
    }
  return out;
}

cv::Mat1b depth_creases(const cv::Mat1f& depth, const cv::Matx33d& K, float min_angle_deg, float max_step_mm) {
  const int W = depth.cols, H = depth.rows;
  cv::Mat3f P(depth.size(), cv::Vec3f(0, 0, 0));
  const cv::Matx33d Kinv = K.inv();
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) P(y, x) = cv::Vec3f(Kinv * cv::Vec3d(x, y, 1) * depth(y, x));
  // Normal from forward differences; invalid (zero) when they cross a jump or background.
  cv::Mat3f N(depth.size(), cv::Vec3f(0, 0, 0));
  for (int y = 0; y + 1 < H; ++y)
    for (int x = 0; x + 1 < W; ++x) {
      const float z = depth(y, x), zx = depth(y, x + 1), zy = depth(y + 1, x);
      if (z <= 0 || zx <= 0 || zy <= 0 || std::abs(zx - z) > max_step_mm || std::abs(zy - z) > max_step_mm) continue;
      const cv::Vec3f n = (P(y, x + 1) - P(y, x)).cross(P(y + 1, x) - P(y, x));
      const double len = cv::norm(n);
      if (len > 0) N(y, x) = n / static_cast<float>(len);
    }
  const float cos_min = std::cos(min_angle_deg * static_cast<float>(CV_PI) / 180.f);
  cv::Mat1b out(depth.size(), 0);
  for (int y = 2; y + 2 < H; ++y)
    for (int x = 2; x + 2 < W; ++x) {
      if (depth(y, x) <= 0) continue;
      const cv::Vec3f pairs[2][2] = {{N(y, x - 2), N(y, x + 1)}, {N(y - 2, x), N(y + 1, x)}};
      for (const auto& pr : pairs)
        if (pr[0] != cv::Vec3f() && pr[1] != cv::Vec3f() && pr[0].dot(pr[1]) < cos_min) out(y, x) = 255;
    }
  return out;
}

EdgeScore score_edges(const cv::Mat1b& detected, const cv::Mat1b& truth, double tolerance_px, int border) {
  CV_Assert(detected.size() == truth.size());
  const cv::Rect inner(border, border, detected.cols - 2 * border, detected.rows - 2 * border);
  cv::Mat1b det(detected.size(), 0), tru(truth.size(), 0);
  detected(inner).copyTo(det(inner));
  truth(inner).copyTo(tru(inner));
  // Distance (L2) from every pixel to the nearest truth / detected pixel.
  cv::Mat1f to_truth, to_detected;
  cv::distanceTransform(255 - tru, to_truth, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  cv::distanceTransform(255 - det, to_detected, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  EdgeScore s;
  int good_detected = 0, found_truth = 0;
  const auto tol = static_cast<float>(tolerance_px + 1e-6);
  for (int y = 0; y < det.rows; ++y)
    for (int x = 0; x < det.cols; ++x) {
      if (det(y, x)) {
        ++s.detected;
        good_detected += to_truth(y, x) <= tol;
      }
      if (tru(y, x)) {
        ++s.truth;
        found_truth += to_detected(y, x) <= tol;
      }
    }
  s.precision = s.detected ? static_cast<double>(good_detected) / s.detected : 0;
  s.recall = s.truth ? static_cast<double>(found_truth) / s.truth : 0;
  return s;
}

}  // namespace mfcd::vision
