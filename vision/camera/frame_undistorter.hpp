#pragma once
// Removes the calibrated lens distortion from camera images: the frame path's undistortion
// (docs/camera.md, "Lens distortion"). The renderer, the templates and the pose code model an
// ideal pinhole with the camera file's K; a real lens bends straight edges by up to several pixels
// towards the image corners, so every image of a frame set is remapped before matching.
//
// The output keeps K (new camera matrix = K, no rectification): an undistorted image is what the
// ideal pinhole with the same K sees, so templates taught for that camera stay valid. Pixels
// whose source falls outside the sensor are 0 (BORDER_CONSTANT).

#include <opencv2/core.hpp>

#include "vision/camera/camera.hpp"

namespace mfcd::vision {

class FrameUndistorter {
 public:
  // A no-op undistorter (nothing to remove).
  FrameUndistorter() = default;
  // Maps for `camera` (image_size, K, distortion), computed once here (allocates). With every
  // distortion coefficient 0 it is a no-op: no maps, active() false.
  explicit FrameUndistorter(const PinholeCamera& camera);

  // False when the camera has no distortion: apply() would only copy, so callers keep their
  // plain copy (or skip the work altogether).
  bool active() const { return !map1_.empty(); }
  const cv::Size& image_size() const { return size_; }

  // dst = src undistorted: bilinear on the fixed-point maps, the result of cv::remap(INTER_LINEAR,
  // BORDER_CONSTANT 0) with them, computed serially without allocating. src: the camera's
  // image_size, CV_8UC1 or CV_16UC1; must not share memory with dst. dst is (re)allocated only
  // when its size or type differ from src's: into a preallocated image of the right size and
  // type nothing allocates. When !active() dst is a plain copy of src. Throws std::logic_error
  // on a src of another size than the camera's, of another type, or sharing dst's pixels.
  void apply(const cv::Mat& src, cv::Mat& dst) const;

 private:
  cv::Size size_;
  cv::Mat map1_;  // CV_16SC2: integer source x, y per output pixel
  cv::Mat map2_;  // CV_16UC1: index of the bilinear sub-pixel weights (cv::INTER_TAB_SIZE^2)
};

}  // namespace mfcd::vision
