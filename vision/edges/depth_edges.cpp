#include "vision/edges/depth_edges.hpp"

#include "vision/common/orientation.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace mfcd::vision {

namespace {

// Tangent angle in [0, pi) of an edge whose normal is (nx, ny).
float tangent_angle(float nx, float ny) {
  float a = std::atan2(ny, nx) + std::numbers::pi_v<float> / 2;
  if (a >= std::numbers::pi_v<float>) a -= std::numbers::pi_v<float>;
  if (a < 0) a += std::numbers::pi_v<float>;
  return a;
}

// Offset to the neighbour in the direction of (nx, ny), quantised to 45 degrees.
void quantise(float nx, float ny, int& ox, int& oy) {
  const float ax = std::abs(nx), ay = std::abs(ny);
  constexpr float tan22 = 0.41421356f;
  ox = ay <= tan22 * ax ? (nx > 0 ? 1 : -1) : (ax <= tan22 * ay ? 0 : (nx > 0 ? 1 : -1));
  oy = ax <= tan22 * ay ? (ny > 0 ? 1 : -1) : (ay <= tan22 * ax ? 0 : (ny > 0 ? 1 : -1));
}

// Angle in [0, 2 pi) of (nx, ny).
float full_angle(float nx, float ny) {
  float a = std::atan2(ny, nx);
  if (a < 0) a += 2 * std::numbers::pi_v<float>;
  return a < 2 * std::numbers::pi_v<float> ? a : 0.f;
}

}  // namespace

float oriented_tangent(float tangent, float shadow) {
  float a = shadow_left_of(tangent, shadow) ? tangent : tangent + std::numbers::pi_v<float>;
  if (a >= 2 * std::numbers::pi_v<float>) a -= 2 * std::numbers::pi_v<float>;
  if (a < 0) a += 2 * std::numbers::pi_v<float>;
  return a;
}

DepthEdgeExtractor::DepthEdgeExtractor(const PinholeCamera& camera, const FlashRing& flashes,
                                       const DepthEdgeParams& params)
    : camera_(camera), params_(params) {
  if (flashes.positions_mm.empty()) throw std::invalid_argument("depth edges: no flash positions");
  if (!(params.low_threshold > 0) || params.low_threshold > params.high_threshold)
    throw std::invalid_argument("depth edges: thresholds must satisfy 0 < low <= high");
  for (const auto& p : flashes.positions_mm) epipoles_.push_back(flash_epipole(camera, p));
  const cv::Size size = camera.image_size;
  max_image_.create(size);
  ratio_.resize(epipoles_.size());
  for (auto& r : ratio_) r.create(size);
  response_.create(size);
  inv_max_.create(size);  // per row, so that rows can run in parallel
  normal_x_.create(size);
  normal_y_.create(size);
  state_.create(size);
  stack_.reserve(static_cast<size_t>(size.area()));
}

void DepthEdgeExtractor::check_input(const MfcFrames& frames) const {
  const cv::Size size = camera_.image_size;
  if (frames.flash.size() != epipoles_.size())
    throw std::invalid_argument("depth edges: expected " + std::to_string(epipoles_.size()) + " flash images, got " +
                                std::to_string(frames.flash.size()));
  for (size_t i = 0; i < frames.flash.size(); ++i)
    if (frames.flash[i].size() != size)
      throw std::invalid_argument("depth edges: flash image " + std::to_string(i) + " is not " +
                                  std::to_string(size.width) + "x" + std::to_string(size.height));
  if (frames.ambient.size() != size) throw std::invalid_argument("depth edges: ambient image has the wrong size");
}

namespace {

// Step 2 of extract() for one flash and one image row y: adds the flash's directional response
// (the Sobel derivative of its ratio image rows r0, r1, r2 = y - 1, y, y + 1 along the shadow
// direction, clipped at 0) to `response`, and the response-weighted gradient to `normal_x/y`.
// The shadow direction at x is (ez x - ex, dy_raw), of length 1 / inv_row when it is the same
// for every pixel (`PerPixel` false: the LED lies in the lens plane). A function with restrict
// parameters (the rows never overlap) so that GCC vectorises the loop: the same IEEE operations
// per pixel in the same order, so the same values as the scalar loop.
template <bool PerPixel>
void accumulate_flash_row(const float* __restrict r0, const float* __restrict r1, const float* __restrict r2,
                          float* __restrict response, float* __restrict normal_x, float* __restrict normal_y, int W,
                          float ex, float ez, float dy_raw, float inv_row) {
  for (int x = 1; x + 1 < W; ++x) {
    const float gx = 0.25f * ((r0[x + 1] - r0[x - 1]) + 2.f * (r1[x + 1] - r1[x - 1]) + (r2[x + 1] - r2[x - 1]));
    const float gy = 0.25f * ((r2[x - 1] + 2.f * r2[x] + r2[x + 1]) - (r0[x - 1] + 2.f * r0[x] + r0[x + 1]));
    const float dx_raw = ez * static_cast<float>(x) - ex;
    const float inv = PerPixel ? 1.f / std::sqrt(dx_raw * dx_raw + dy_raw * dy_raw + 1e-20f) : inv_row;
    const float along = -(gx * dx_raw + gy * dy_raw) * inv;
    const float r = std::max(along, 0.f);
    // Weighting by the response keeps the normal continuous in the inputs: a flash
    // barely seeing the edge barely contributes.
    response[x] += r;
    normal_x[x] -= r * gx;
    normal_y[x] -= r * gy;
  }
}

}  // namespace

void DepthEdgeExtractor::extract(const MfcFrames& frames, DepthEdges& out) {
  check_input(frames);
  const int W = camera_.image_size.width, H = camera_.image_size.height;
  const size_t n = epipoles_.size();

  // 1. Ambient subtraction, max image (eq. 17) and ratio images (eq. 18).
  const float min_flash = params_.min_flash_dn;
  // Rows are independent in steps 1 and 2: shared among the cores.
#pragma omp parallel for schedule(static)
  for (int y = 0; y < H; ++y) {
    const uint8_t* amb = frames.ambient.ptr<uint8_t>(y);
    float* mx = max_image_.ptr<float>(y);
    for (int x = 0; x < W; ++x) mx[x] = 0.f;
    for (size_t i = 0; i < n; ++i) {
      const uint8_t* f = frames.flash[i].ptr<uint8_t>(y);
      float* r = ratio_[i].ptr<float>(y);
      for (int x = 0; x < W; ++x) {
        const float v = std::max(static_cast<float>(f[x]) - static_cast<float>(amb[x]), 0.f);
        r[x] = v;
        mx[x] = std::max(mx[x], v);
      }
    }
    float* inv = inv_max_.ptr<float>(y);
    // The division on a select's other arm would be a possible trap the compiler may not
    // speculate: divide by 1 there instead, so that the loop has no branch.
    for (int x = 0; x < W; ++x) {
      const bool lit = mx[x] >= min_flash;
      const float q = 1.f / (lit ? mx[x] : 1.f);
      inv[x] = lit ? q : 0.f;
    }
    for (size_t i = 0; i < n; ++i) {
      float* r = ratio_[i].ptr<float>(y);
      for (int x = 0; x < W; ++x) r[x] = inv[x] > 0.f ? r[x] * inv[x] : 1.f;
    }
  }

  // 2. Per flash, the Sobel derivative of the ratio image along the shadow direction at
  //    each pixel (away from the LED's epipole). A depth edge is a lit-to-shadow step
  //    along that direction: a negative derivative. Responses of all flashes are summed,
  //    and so are their gradients (weighted by the response), whose direction is the edge normal.
  // Cleared by hand: Mat::setTo allocates on every call (the maps are continuous, made by create()).
  std::fill_n(response_.ptr<float>(), response_.total(), 0.f);
  std::fill_n(normal_x_.ptr<float>(), normal_x_.total(), 0.f);
  std::fill_n(normal_y_.ptr<float>(), normal_y_.total(), 0.f);
  const float dim2 = params_.dim_flash_dn * params_.dim_flash_dn;
#pragma omp parallel for schedule(static)
  for (int y = 1; y < H - 1; ++y) {
    float* s = response_.ptr<float>(y);
    float* gx_sum = normal_x_.ptr<float>(y);
    float* gy_sum = normal_y_.ptr<float>(y);
    const float* mx = max_image_.ptr<float>(y);
    for (size_t i = 0; i < n; ++i) {
      const float* r0 = ratio_[i].ptr<float>(y - 1);
      const float* r1 = ratio_[i].ptr<float>(y);
      const float* r2 = ratio_[i].ptr<float>(y + 1);
      const auto ex = static_cast<float>(epipoles_[i].ex), ey = static_cast<float>(epipoles_[i].ey),
                 ez = static_cast<float>(epipoles_[i].ez);
      const float dy_raw = ez * static_cast<float>(y) - ey;
      // An LED in the lens plane (ez = 0) has its epipole at infinity: one direction for
      // the whole image, normalised once per row instead of per pixel.
      const bool constant = ez == 0.f;
      const float inv_row = constant ? 1.f / std::sqrt(ex * ex + ey * ey + 1e-20f) : 0.f;
      if (constant)
        accumulate_flash_row<false>(r0, r1, r2, s, gx_sum, gy_sum, W, ex, ez, dy_raw, inv_row);
      else
        accumulate_flash_row<true>(r0, r1, r2, s, gx_sum, gy_sum, W, ex, ez, dy_raw, inv_row);
    }
    for (int x = 1; x + 1 < W; ++x) s[x] *= mx[x] * mx[x] / (mx[x] * mx[x] + dim2);
  }

  // 3. Non-maximum suppression of the summed response across the edge (along the summed
  //    normal, quantised to 45 degrees). Of two equal neighbours the one on the occluding
  //    side (against the normal, which points into the shadow) is kept.
  const float lo = params_.low_threshold, hi = params_.high_threshold;
  std::fill_n(state_.ptr<uint8_t>(), state_.total(), uint8_t(0));
  stack_.clear();
  for (int y = 2; y + 2 < H; ++y) {
    const float* s = response_.ptr<float>(y);
    const float* nx = normal_x_.ptr<float>(y);
    const float* ny = normal_y_.ptr<float>(y);
    uint8_t* st = state_.ptr<uint8_t>(y);
    for (int x = 2; x + 2 < W; ++x) {
      const float v = s[x];
      if (v < lo) continue;
      int ox = 0, oy = 0;
      quantise(nx[x], ny[x], ox, oy);
      const float ahead = response_(y + oy, x + ox), behind = response_(y - oy, x - ox);
      if (!(v >= ahead && v > behind)) continue;
      st[x] = 1;
      if (v >= hi) {
        st[x] = 2;
        stack_.push_back(y * W + x);
      }
    }
  }

  // 4. Hysteresis: weak maxima connected (8-neighbourhood) to strong ones become edges.
  while (!stack_.empty()) {
    const int p = stack_.back();
    stack_.pop_back();
    const int y = p / W, x = p % W;
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        uint8_t& q = state_(y + dy, x + dx);  // border pixels are never 1: no bounds check needed
        if (q == 1) {
          q = 2;
          stack_.push_back((y + dy) * W + x + dx);
        }
      }
  }

  out.edges.create(H, W);
  out.direction.create(H, W);
  out.shadow.create(H, W);
  for (int y = 0; y < H; ++y) {
    const uint8_t* st = state_.ptr<uint8_t>(y);
    const float* nx = normal_x_.ptr<float>(y);
    const float* ny = normal_y_.ptr<float>(y);
    uint8_t* e = out.edges.ptr<uint8_t>(y);
    float* d = out.direction.ptr<float>(y);
    float* sh = out.shadow.ptr<float>(y);
    for (int x = 0; x < W; ++x) {
      const bool edge = st[x] == 2;
      e[x] = edge ? 255 : 0;
      d[x] = edge ? tangent_angle(nx[x], ny[x]) : 0.f;
      sh[x] = edge ? full_angle(nx[x], ny[x]) : 0.f;
    }
  }
}

void CannyEdgeDetector::detect(const cv::Mat1b& image, DepthEdges& out) {
  cv::Sobel(image, dx_, CV_16S, 1, 0, 3);
  cv::Sobel(image, dy_, CV_16S, 0, 1, 3);
  cv::Canny(dx_, dy_, out.edges, low_, high_, true);
  out.shadow.release();  // intensity edges do not say which side is nearer
  out.direction.create(image.size());
  for (int y = 0; y < image.rows; ++y) {
    const uint8_t* e = out.edges.ptr<uint8_t>(y);
    const int16_t* gx = dx_.ptr<int16_t>(y);
    const int16_t* gy = dy_.ptr<int16_t>(y);
    float* d = out.direction.ptr<float>(y);
    for (int x = 0; x < image.cols; ++x) d[x] = e[x] ? tangent_angle(gx[x], gy[x]) : 0.f;
  }
}

}  // namespace mfcd::vision
