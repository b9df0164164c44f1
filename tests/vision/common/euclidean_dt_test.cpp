#include <gtest/gtest.h>

#include <random>

#include "vision/common/euclidean_dt.hpp"

using namespace mfcd::vision;

// Twin: brute-force minimum over all sites.
TEST(EuclideanDistance, EqualsBruteForceOnRandomSites) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    const int w = 10 + static_cast<int>(rng() % 50), h = 10 + static_cast<int>(rng() % 40);
    cv::Mat1b sites(h, w, uchar(0));
    const int count = static_cast<int>(rng() % 30);
    std::vector<cv::Point> pts;
    for (int i = 0; i < count; ++i) {
      cv::Point p(static_cast<int>(rng() % w), static_cast<int>(rng() % h));
      sites(p) = 1;
      pts.push_back(p);
    }
    cv::Mat1i d2, nearest;
    squaredEuclideanDistance(sites, d2, &nearest);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        int best = kInfiniteDistance2;
        for (const auto& p : pts) best = std::min(best, (p.x - x) * (p.x - x) + (p.y - y) * (p.y - y));
        ASSERT_EQ(d2(y, x), best) << "at " << x << "," << y;
        if (pts.empty()) {
          EXPECT_EQ(nearest(y, x), kNoSite);
        } else {
          const int n = nearest(y, x), nx = n % w, ny = n / w;
          EXPECT_TRUE(sites(ny, nx));
          EXPECT_EQ((nx - x) * (nx - x) + (ny - y) * (ny - y), best);
        }
      }
  }
}
