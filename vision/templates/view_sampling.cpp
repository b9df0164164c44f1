#include "vision/templates/view_sampling.hpp"

#include <cmath>
#include <stdexcept>

namespace mfcd::vision {

std::vector<cv::Vec3d> fibonacci_sphere(int K) {
  if (K < 1) throw std::invalid_argument("sphere samples K = " + std::to_string(K) + " must be >= 1");
  const double golden = CV_PI * (3.0 - std::sqrt(5.0));
  std::vector<cv::Vec3d> out;
  out.reserve(K);
  for (int i = 0; i < K; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / K;
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    const double a = golden * i;
    out.emplace_back(r * std::cos(a), r * std::sin(a), z);
  }
  return out;
}

std::vector<cv::Vec3d> template_view_directions(int K, const PartSymmetry& symmetry) {
  if (symmetry.kind == PartSymmetry::Kind::continuous_z) {
    const double spacing = std::sqrt(4 * CV_PI / K);
    const int n = std::max(2, static_cast<int>(std::ceil(CV_PI / spacing)) + 1);
    std::vector<cv::Vec3d> out;
    for (int j = 0; j < n; ++j) {
      const double polar = CV_PI * j / (n - 1);
      out.emplace_back(std::sin(polar), 0.0, std::cos(polar));
    }
    return out;
  }
  std::vector<cv::Vec3d> all = fibonacci_sphere(K);
  if (symmetry.kind != PartSymmetry::Kind::discrete_z) return all;
  const double wedge = 2 * CV_PI / symmetry.order;
  std::vector<cv::Vec3d> out;
  for (const auto& d : all) {
    double az = std::atan2(d[1], d[0]);
    if (az < 0) az += 2 * CV_PI;
    if (az < wedge) out.push_back(d);
  }
  return out;
}

cv::Matx33d view_rotation(const cv::Vec3d& d_in) {
  const cv::Vec3d d = cv::normalize(d_in);
  const cv::Vec3d z = -d;  // camera forward, in model coordinates
  // Camera x: perpendicular to forward and to the model z axis, unless looking along z.
  cv::Vec3d ref(0, 0, 1);
  if (std::abs(z.dot(ref)) > 0.999) ref = cv::Vec3d(0, 1, 0);
  const cv::Vec3d x = cv::normalize(ref.cross(z));
  const cv::Vec3d y = z.cross(x);
  // Rows are the camera axes in model coordinates: p_cam = R p_model.
  return cv::Matx33d(x[0], x[1], x[2], y[0], y[1], y[2], z[0], z[1], z[2]);
}

}  // namespace mfcd::vision
