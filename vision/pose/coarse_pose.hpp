#pragma once
// Coarse 3-D pose from an FDCM match (paper Sec. 4.4-4.5): the matched template view gives the
// out-of-plane rotation, the search gives the in-plane rotation, scale and where the template
// origin (the image of the part centre) lands. Back-projection with K: the part centre goes on
// the ray through that pixel at the view's distance divided by the scale, and the view's
// rotation is turned with the ray, so the part keeps the appearance the template had on the
// optical axis.

#include "vision/camera/camera.hpp"
#include "vision/templates/template_database.hpp"

#include <opencv2/core.hpp>

namespace mfcd::vision {

struct RigidPose {
  cv::Matx33d R = cv::Matx33d::eye();  // model -> camera
  cv::Vec3d t_mm{0, 0, 0};
};

struct TemplatePlacement {
  int view = 0;           // index into TemplateDatabase::views
  double angle_rad = 0;   // in-plane rotation of the template (image axes: x turns towards y)
  double scale = 1;       // image scale relative to the template (distance ratio view / actual)
  cv::Point2d origin_px;  // where the template origin (image of the part centre) lands
};

// The rotation taking the optical axis (0, 0, 1) onto the unit ray through `pixel`, about the
// axis perpendicular to both (the smallest such rotation).
cv::Matx33d ray_alignment(const PinholeCamera& camera, const cv::Point2d& pixel);

RigidPose coarse_pose(const TemplateDatabase& db, const TemplatePlacement& placement, const PinholeCamera& camera);

// The inverse for a given view: the placement whose coarse pose is closest to `pose`
// (exact when the pose was made by coarse_pose with that view).
TemplatePlacement placement_of(const TemplateDatabase& db, int view, const RigidPose& pose,
                               const PinholeCamera& camera);

}  // namespace mfcd::vision
