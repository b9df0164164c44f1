#pragma once
// Ground truth for edge maps from a rendered depth buffer, and precision/recall within a
// pixel tolerance.

#include <opencv2/core.hpp>

namespace mfcd::vision {

// Pixels on the near (occluding) side of a depth discontinuity: a surface pixel with a
// 4-neighbour that is farther by more than min_jump_mm or shows no surface (depth 0).
cv::Mat1b depth_discontinuities(const cv::Mat1f& depth_mm, float min_jump_mm);

// Creases: surface pixels where the surface normal (from the back-projected depth buffer,
// one-sided differences) turns by more than min_angle_deg between the pixels on either
// side, with no depth jump in between. MFC images also respond there when one of the two
// faces is seen at a grazing angle and so lies in an attached shadow of some flashes.
cv::Mat1b depth_creases(const cv::Mat1f& depth_mm, const cv::Matx33d& K, float min_angle_deg, float max_step_mm);

struct EdgeScore {
  int detected = 0, truth = 0;
  double precision = 0;  // detected pixels within tolerance of a truth pixel
  double recall = 0;     // truth pixels within tolerance of a detected pixel
};

// Pixels closer than `border` to the image border are ignored in both maps.
EdgeScore score_edges(const cv::Mat1b& detected, const cv::Mat1b& truth, double tolerance_px, int border = 2);

}  // namespace mfcd::vision
