#pragma once
// Exact Euclidean distance transform (Felzenszwalb & Huttenlocher's lower envelope of parabolas),
// with the nearest site of every pixel. Used by the CM/OCM baselines; DT3 has its own truncated,
// per-channel variant in vision/dt3 that is tested against this one.
#include <opencv2/core/mat.hpp>

namespace mfcd::vision {

inline constexpr int kNoSite = -1;
inline constexpr int kInfiniteDistance2 = 1 << 30;

// d2(y, x) = min over sites s (sites(s) != 0) of |x - s|^2, or kInfiniteDistance2 without sites.
// If nearest != nullptr it receives, per pixel, the index y*width + x of one nearest site
// (kNoSite without sites).
void squaredEuclideanDistance(const cv::Mat1b& sites, cv::Mat1i& d2, cv::Mat1i* nearest = nullptr);

}  // namespace mfcd::vision
