#pragma once
// Depth edges from multi-flash images (paper Section 4.2): ambient subtraction, max image,
// ratio images, a Sobel derivative along each flash's epipolar (shadow) direction,
// non-maximum suppression and hysteresis. Plus Canny for the gripper camera, with the
// same output type.

#include "vision/camera/camera.hpp"
#include "vision/camera/mfc_frames.hpp"

#include <opencv2/core.hpp>

#include <array>
#include <vector>

namespace mfcd::vision {

struct DepthEdges {
  cv::Mat1b edges;      // 255 = edge
  cv::Mat1f direction;  // edge tangent angle in radians, [0, pi), image axes (x right, y down); 0 off edges
  // Which side of each edge is the near one: the angle in [0, 2 pi) of the edge normal pointing
  // into the shadow, i.e. away from the occluding surface; 0 off edges. Empty when the detector
  // cannot tell (Canny intensity edges).
  cv::Mat1f shadow;
};

// The chain tangent `tangent` ([0, pi)) turned by pi where needed so that its left normal
// (-sin, cos) points to the shadow side given by `shadow` (an angle as in DepthEdges::shadow):
// an oriented tangent in [0, 2 pi) that carries which side of the edge is the occluder.
float oriented_tangent(float tangent, float shadow);

struct DepthEdgeParams {
  // Pixels whose brightest flash adds less than this (grey levels above ambient) carry no
  // shadow information; their ratios are set to 1 so they produce no edges.
  float min_flash_dn = 3.0f;
  // Ratios of dim pixels are dominated by sensor noise. The summed response is weighted by
  // Imax^2 / (Imax^2 + dim_flash_dn^2): about 1 on lit surfaces, small where even the
  // brightest flash adds only a few grey levels (dark paint on grazing faces).
  float dim_flash_dn = 12.0f;
  // Hysteresis thresholds on the summed directional response. A full lit-to-shadow step
  // seen by one flash perpendicular to the edge gives 1; typically three flashes see an
  // edge, so clean edges score about 2.
  float high_threshold = 0.7f;
  float low_threshold = 0.3f;
};

class DepthEdgeExtractor {
 public:
  // Buffers for camera.image_size are allocated here; extract() then allocates nothing.
  DepthEdgeExtractor(const PinholeCamera& camera, const FlashRing& flashes, const DepthEdgeParams& params = {});

  // frames.flash must hold one image per LED of `flashes`, all of the camera's size.
  // Throws std::invalid_argument naming the mismatching image otherwise.
  void extract(const MfcFrames& frames, DepthEdges& out);

  const DepthEdgeParams& params() const { return params_; }
  // Intermediate images of the last extract(), for inspection and tests.
  const cv::Mat1f& max_image() const { return max_image_; }
  const cv::Mat1f& ratio(size_t flash) const { return ratio_[flash]; }
  const cv::Mat1f& response() const { return response_; }  // summed directional response

 private:
  void check_input(const MfcFrames& frames) const;
  PinholeCamera camera_;
  std::vector<FlashEpipole> epipoles_;
  DepthEdgeParams params_;
  cv::Mat1f max_image_;
  std::vector<cv::Mat1f> ratio_;
  cv::Mat1f response_, normal_x_, normal_y_, inv_max_;
  cv::Mat1b state_;         // 0 none, 1 weak, 2 edge
  std::vector<int> stack_;  // hysteresis work list, reserved to the image size
};

// Canny intensity edges for the gripper camera (no flashes there); direction is the
// tangent of the intensity gradient.
class CannyEdgeDetector {
 public:
  CannyEdgeDetector(double low_threshold, double high_threshold) : low_(low_threshold), high_(high_threshold) {}
  void detect(const cv::Mat1b& image, DepthEdges& out);

 private:
  double low_, high_;
  cv::Mat dx_, dy_;
};

}  // namespace mfcd::vision
