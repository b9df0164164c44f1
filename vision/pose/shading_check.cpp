#include "vision/pose/shading_check.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>

namespace mfcd::vision {

namespace {

constexpr size_t kMaxFlashes = 16;

}  // namespace

void ShadingParams::validate() const {
  auto fail = [](const std::string& what) { throw std::invalid_argument("shading check: " + what); };
  if (margin_px < 0 || margin_px > 64) fail("margin_px " + std::to_string(margin_px) + " out of range [0, 64]");
  if (erode_px < 0 || erode_px > 16) fail("erode_px " + std::to_string(erode_px) + " out of range [0, 16]");
  if (!(max_step_mm > 0)) fail("max_step_mm must be > 0");
  if (!(min_signal_dn >= 0)) fail("min_signal_dn must be >= 0");
  if (!(saturated_dn > 0 && saturated_dn <= 256)) fail("saturated_dn out of range (0, 256]");
  if (!(min_flash_ratio >= 0 && min_flash_ratio < 1)) fail("min_flash_ratio out of range [0, 1)");
  if (!(keep_fraction > 0 && keep_fraction <= 1)) fail("keep_fraction out of range (0, 1]");
}

ShadingCheck::ShadingCheck(MfcRenderer& renderer, const ShadingParams& params)
    : renderer_(renderer), params_(params), scene_(1) {
  params_.validate();
  scene_[0].material = Material::matte(0.7f);
}

ShadingAgreement ShadingCheck::compare(const MfcFrames& frames, const PinholeCamera& camera, const PoseModel& model,
                                       const RigidTransform& m2c) {
  const std::optional<cv::Rect> window = pose_window(camera, model, m2c, params_.margin_px, "shading check");
  if (!window) return {};
  render_at(camera.cropped(*window), model, m2c);
  return compare_in(frames, *window);
}

ShadingAgreement ShadingCheck::compare_whole_image(const MfcFrames& frames, const PinholeCamera& camera,
                                                   const PoseModel& model, const RigidTransform& m2c) {
  render_at(camera, model, m2c);
  return compare_in(frames, cv::Rect(0, 0, camera.image_size.width, camera.image_size.height));
}

void ShadingCheck::render_at(const PinholeCamera& camera, const PoseModel& model, const RigidTransform& m2c) {
  renderer_.set_camera(camera);
  scene_[0].mesh_id = model.mesh_id;
  scene_[0].R = m2c.R;
  scene_[0].t_mm = m2c.t;
  renderer_.render(scene_, render_);
}

// The rendered part's pixels of `window` (full-image coordinates; render_ is its size) against
// the same pixels of the images.
ShadingAgreement ShadingCheck::compare_in(const MfcFrames& frames, const cv::Rect& window) {
  // As many flash images as the renderer makes (eight), and the ambient one.
  const size_t n = render_.flash_linear.size();
  if (frames.flash.size() != n || n > kMaxFlashes || frames.ambient.empty())
    throw std::invalid_argument("shading check: needs the " + std::to_string(n) +
                                " flash images and the ambient one (got " + std::to_string(frames.flash.size()) + ")");
  const cv::Size image = frames.ambient.size();
  const int r = params_.erode_px;
  cv::compare(render_.part_index, 0, mask_, cv::CMP_GT);
  if (r > 0) cv::erode(mask_, mask_, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * r + 1, 2 * r + 1)));
  const cv::Mat1f& depth = render_.depth_mm;
  auto flat = [&](int x, int y) {
    const float z = depth(y, x);
    const float step = params_.max_step_mm;
    return std::abs(depth(y, x - 1) - z) <= step && std::abs(depth(y, x + 1) - z) <= step &&
           std::abs(depth(y - 1, x) - z) <= step && std::abs(depth(y + 1, x) - z) <= step;
  };
  deviations_.clear();
  std::array<float, kMaxFlashes> seen{}, rendered{};
  for (int y = 1; y < mask_.rows - 1; ++y) {
    const int iy = y + window.y;
    if (iy < 0 || iy >= image.height) continue;
    for (int x = 1; x < mask_.cols - 1; ++x) {
      const int ix = x + window.x;
      if (ix < 0 || ix >= image.width || !mask_(y, x) || !flat(x, y)) continue;
      const float ambient = frames.ambient(iy, ix);
      const float rendered_ambient = render_.ambient_linear(y, x);
      bool clipped = false;
      float seen_sum = 0, rendered_sum = 0;
      for (size_t k = 0; k < n; ++k) {
        const float v = frames.flash[k](iy, ix);
        clipped = clipped || v >= params_.saturated_dn;
        seen[k] = v - ambient;
        rendered[k] = render_.flash_linear[k](y, x) - rendered_ambient;
        seen_sum += seen[k];
        rendered_sum += rendered[k];
      }
      if (clipped || seen_sum < params_.min_signal_dn || !(rendered_sum > 0)) continue;
      const auto end = static_cast<std::ptrdiff_t>(n);
      const auto [seen_lo, seen_hi] = std::minmax_element(seen.begin(), seen.begin() + end);
      const auto [rendered_lo, rendered_hi] = std::minmax_element(rendered.begin(), rendered.begin() + end);
      if (*seen_lo < params_.min_flash_ratio * *seen_hi || *rendered_lo < params_.min_flash_ratio * *rendered_hi)
        continue;
      // Each flash's share relative to an even share: n * v / sum.
      double squared = 0;
      for (size_t k = 0; k < n; ++k) {
        const double d = static_cast<double>(n) *
                         (static_cast<double>(seen[k]) / seen_sum - static_cast<double>(rendered[k]) / rendered_sum);
        squared += d * d;
      }
      deviations_.push_back(squared / static_cast<double>(n));
    }
  }
  ShadingAgreement out;
  out.pixels = static_cast<int>(deviations_.size());
  if (deviations_.empty()) return out;
  const size_t keep = std::max<size_t>(1, static_cast<size_t>(std::ceil(params_.keep_fraction * deviations_.size())));
  std::nth_element(deviations_.begin(), deviations_.begin() + static_cast<std::ptrdiff_t>(keep - 1), deviations_.end());
  double sum = 0;
  for (size_t i = 0; i < keep; ++i) sum += deviations_[i];
  out.error = std::sqrt(sum / static_cast<double>(keep));
  return out;
}

}  // namespace mfcd::vision
