#include "vision/camera/frame_undistorter.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cstdint>
#include <stdexcept>
#include <string>

namespace mfcd::vision {

FrameUndistorter::FrameUndistorter(const PinholeCamera& camera) : size_(camera.image_size) {
  const bool distorted =
      std::any_of(camera.distortion.begin(), camera.distortion.end(), [](double d) { return d != 0.0; });
  if (!distorted) return;
  // New camera matrix = K: the undistorted image is the ideal pinhole of the same K (templates
  // stay valid). Float maps first, then the fixed-point pair (integer pixel + 5-bit fractions)
  // that apply() samples with integer arithmetic.
  cv::Mat mapx, mapy;
  cv::initUndistortRectifyMap(cv::Mat(camera.K), cv::Mat(camera.distortion), cv::noArray(), cv::Mat(camera.K), size_,
                              CV_32FC1, mapx, mapy);
  cv::convertMaps(mapx, mapy, map1_, map2_, CV_16SC2, false);
}

namespace {

// Bilinear sampling on OpenCV's fixed-point maps, what cv::remap(INTER_LINEAR, BORDER_CONSTANT 0)
// computes from them (weights (32 - fx | fx) x (32 - fy | fy) / 1024, rounded), done here in one
// serial pass: cv::remap runs through cv::parallel_for_, whose TBB back end allocates on every
// call (~10 operator new per image, seen by the allocation-counter test), and the frame path
// must not allocate. T: uchar or ushort.
template <typename T>
void remap_bilinear(const cv::Mat& src, cv::Mat& dst, const cv::Mat& map1, const cv::Mat& map2) {
  constexpr int kBits = 5;           // cv::INTER_BITS
  constexpr int kTab = 1 << kBits;   // cv::INTER_TAB_SIZE
  constexpr int kOne = kTab * kTab;  // the weights' sum
  const int w = src.cols, h = src.rows;
  const std::uint8_t* const base = src.data;
  const std::size_t step = src.step[0];
  const auto row = [base, step](int v) {
    return reinterpret_cast<const T*>(base + static_cast<std::size_t>(v) * step);
  };
  for (int y = 0; y < dst.rows; ++y) {
    const cv::Vec2s* xy = map1.ptr<cv::Vec2s>(y);
    const std::uint16_t* frac = map2.ptr<std::uint16_t>(y);
    T* out = dst.ptr<T>(y);
    for (int x = 0; x < dst.cols; ++x) {
      const int sx = xy[x][0], sy = xy[x][1];
      const int fx = frac[x] & (kTab - 1), fy = frac[x] >> kBits;
      const int w00 = (kTab - fx) * (kTab - fy), w01 = fx * (kTab - fy), w10 = (kTab - fx) * fy, w11 = fx * fy;
      int sum;
      if (static_cast<unsigned>(sx) < static_cast<unsigned>(w - 1) &&
          static_cast<unsigned>(sy) < static_cast<unsigned>(h - 1)) {
        const T* r0 = row(sy) + sx;
        const T* r1 = row(sy + 1) + sx;
        sum = r0[0] * w00 + r0[1] * w01 + r1[0] * w10 + r1[1] * w11;
      } else {  // at the border: samples outside the image count as 0
        const auto at = [&](int u, int v) -> int { return u >= 0 && u < w && v >= 0 && v < h ? row(v)[u] : 0; };
        sum = at(sx, sy) * w00 + at(sx + 1, sy) * w01 + at(sx, sy + 1) * w10 + at(sx + 1, sy + 1) * w11;
      }
      out[x] = static_cast<T>((sum + kOne / 2) >> (2 * kBits));
    }
  }
}

}  // namespace

void FrameUndistorter::apply(const cv::Mat& src, cv::Mat& dst) const {
  if (src.size() != size_)
    throw std::logic_error("FrameUndistorter: a " + std::to_string(src.cols) + "x" + std::to_string(src.rows) +
                           " image for a " + std::to_string(size_.width) + "x" + std::to_string(size_.height) +
                           " camera");
  if (!active()) {
    src.copyTo(dst);
    return;
  }
  if (src.type() != CV_8UC1 && src.type() != CV_16UC1)
    throw std::logic_error("FrameUndistorter: images of 8 or 16 bits, one channel");
  if (src.data == dst.data) throw std::logic_error("FrameUndistorter: src and dst share their pixels");
  dst.create(src.size(), src.type());  // a no-op for a dst of the right size and type
  if (src.depth() == CV_8U)
    remap_bilinear<std::uint8_t>(src, dst, map1_, map2_);
  else
    remap_bilinear<std::uint16_t>(src, dst, map1_, map2_);
}

}  // namespace mfcd::vision
