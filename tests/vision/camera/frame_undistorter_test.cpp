// FrameUndistorter: a no-op without distortion; otherwise cv::remap's INTER_LINEAR result on the
// same fixed-point maps (8 and 16 bits), written into a preallocated image without allocating;
// the cost per frame set (9 images of the simulated camera's 640x480) is printed.
#include "vision/camera/frame_undistorter.hpp"

#include "tests/hal/alloc_counter.hpp"

#include <gtest/gtest.h>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <chrono>
#include <cstdio>

using namespace mfcd::vision;

namespace {

PinholeCamera lens(std::vector<double> distortion) {
  PinholeCamera c;
  c.image_size = {640, 480};
  c.K = cv::Matx33d(1100, 0, 319.5, 0, 1100, 239.5, 0, 0, 1);
  c.distortion = std::move(distortion);
  return c;
}

cv::Mat random_image(int type, uint64_t seed) {
  cv::Mat m(480, 640, type);
  cv::RNG rng(seed);
  rng.fill(m, cv::RNG::UNIFORM, 0, type == CV_8UC1 ? 256 : 4096);
  cv::GaussianBlur(m, m, cv::Size(5, 5), 1.5);  // image-like: neighbours correlate
  return m;
}

}  // namespace

TEST(FrameUndistorter, NoDistortionIsANoOpCopy) {
  const FrameUndistorter u(lens({0, 0, 0, 0, 0}));
  EXPECT_FALSE(u.active());
  const cv::Mat src = random_image(CV_8UC1, 1);
  cv::Mat dst;
  u.apply(src, dst);
  EXPECT_EQ(cv::norm(src, dst, cv::NORM_INF), 0.0);
  EXPECT_FALSE(FrameUndistorter().active());
}

TEST(FrameUndistorter, MatchesOpenCvRemapOnTheSameMaps) {
  const PinholeCamera cam = lens({-0.2, 0.05, 0.001, -0.0005, 0.0});
  const FrameUndistorter u(cam);
  ASSERT_TRUE(u.active());
  cv::Mat mapx, mapy, map1, map2;
  cv::initUndistortRectifyMap(cv::Mat(cam.K), cv::Mat(cam.distortion), cv::noArray(), cv::Mat(cam.K), cam.image_size,
                              CV_32FC1, mapx, mapy);
  cv::convertMaps(mapx, mapy, map1, map2, CV_16SC2, false);
  for (int type : {CV_8UC1, CV_16UC1}) {
    const cv::Mat src = random_image(type, 7);
    cv::Mat want, got;
    cv::remap(src, want, map1, map2, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
    u.apply(src, got);
    ASSERT_EQ(got.type(), type);
    EXPECT_LE(cv::norm(want, got, cv::NORM_INF), 1.0) << "type " << type;
    EXPECT_GT(cv::norm(src, got, cv::NORM_INF), 10.0) << "the image was not moved";
    // K kept: next to the principal point nothing moves.
    cv::Mat a, b;
    src(cv::Rect(310, 230, 20, 20)).convertTo(a, CV_32F);
    got(cv::Rect(310, 230, 20, 20)).convertTo(b, CV_32F);
    EXPECT_LE(cv::norm(a, b, cv::NORM_INF), 1.0);
  }
}

TEST(FrameUndistorter, BarrelMovesACornerPointBackToItsIdealPlace) {
  // A bright dot where the lens shows the ideal point (600, 450) - cv::projectPoints with the
  // distortion - comes back to (600, 450) within a pixel after undistortion.
  const PinholeCamera cam = lens({-0.2, 0.05, 0.0, 0.0, 0.0});
  const cv::Point2d ideal(600, 450);
  const cv::Vec3d ray((ideal.x - cam.cx()) / cam.fx(), (ideal.y - cam.cy()) / cam.fy(), 1.0);
  std::vector<cv::Point2d> seen;
  cv::projectPoints(std::vector<cv::Vec3d>{ray}, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), cv::Mat(cam.K),
                    cv::Mat(cam.distortion), seen);
  ASSERT_GT(cv::norm(seen[0] - ideal), 5.0) << "the lens moves the corner point by several pixels";
  cv::Mat1b distorted(480, 640, uchar(0));
  cv::circle(distorted, cv::Point(cvRound(seen[0].x * 16), cvRound(seen[0].y * 16)), 3 * 16, cv::Scalar(255),
             cv::FILLED, cv::LINE_AA, 4);
  cv::Mat undistorted;
  FrameUndistorter(cam).apply(distorted, undistorted);
  const cv::Moments m = cv::moments(undistorted);
  const cv::Point2d centroid(m.m10 / m.m00, m.m01 / m.m00);
  EXPECT_LT(cv::norm(centroid - ideal), 1.0) << centroid;
}

TEST(FrameUndistorter, IntoAPreallocatedImageNothingIsAllocated) {
  const FrameUndistorter u(lens({-0.2, 0.05, 0.0, 0.0, 0.0}));
  std::vector<cv::Mat> src, dst;
  for (int k = 0; k < 9; ++k) {
    src.push_back(random_image(CV_8UC1, static_cast<uint64_t>(k)));
    dst.emplace_back(480, 640, CV_8UC1);
  }
  for (int k = 0; k < 9; ++k) u.apply(src[static_cast<size_t>(k)], dst[static_cast<size_t>(k)]);  // warm-up
  const int kRounds = 20;
  const std::uint64_t before = mfcd::hal::test::allocation_count();
  const auto t0 = std::chrono::steady_clock::now();
  for (int r = 0; r < kRounds; ++r)
    for (int k = 0; k < 9; ++k) u.apply(src[static_cast<size_t>(k)], dst[static_cast<size_t>(k)]);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() / kRounds;
  const std::uint64_t after = mfcd::hal::test::allocation_count();
  EXPECT_EQ(after - before, 0u);
  std::printf("undistortion: %.2f ms per frame set (9 images, 640x480, 8 bits)\n", ms);
  // For the record: cv::remap on the same maps, which allocates on every call.
  cv::Mat mapx, mapy, map1, map2;
  const PinholeCamera cam = lens({-0.2, 0.05, 0.0, 0.0, 0.0});
  cv::initUndistortRectifyMap(cv::Mat(cam.K), cv::Mat(cam.distortion), cv::noArray(), cv::Mat(cam.K), cam.image_size,
                              CV_32FC1, mapx, mapy);
  cv::convertMaps(mapx, mapy, map1, map2, CV_16SC2, false);
  const std::uint64_t cv_before = mfcd::hal::test::allocation_count();
  const auto t1 = std::chrono::steady_clock::now();
  for (int r = 0; r < kRounds; ++r)
    for (int k = 0; k < 9; ++k)
      cv::remap(src[static_cast<size_t>(k)], dst[static_cast<size_t>(k)], map1, map2, cv::INTER_LINEAR,
                cv::BORDER_CONSTANT);
  const double cv_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t1).count() / kRounds;
  std::printf("cv::remap: %.2f ms per frame set, %.1f allocations per image\n", cv_ms,
              double(mfcd::hal::test::allocation_count() - cv_before) / (kRounds * 9));
}
