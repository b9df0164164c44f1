#include "vision/pose/coarse_pose.hpp"

#include <cmath>
#include <stdexcept>

#include "vision/pose/rigid_transform.hpp"

namespace mfcd::vision {

namespace {
cv::Vec3d unit_ray(const PinholeCamera& camera, const cv::Point2d& p) {
  return cv::normalize(cv::Vec3d((p.x - camera.cx()) / camera.fx(), (p.y - camera.cy()) / camera.fy(), 1.0));
}
}  // namespace

cv::Matx33d ray_alignment(const PinholeCamera& camera, const cv::Point2d& pixel) {
  const cv::Vec3d z(0, 0, 1), r = unit_ray(camera, pixel);
  const cv::Vec3d axis = z.cross(r);
  const double s = cv::norm(axis), c = z.dot(r);
  if (s < 1e-12) return cv::Matx33d::eye();
  // Rodrigues' formula by hand: cv::Rodrigues allocates, and this runs for every hypothesis fit.
  return rotation_from_angle_axis(axis * (std::atan2(s, c) / s));
}

RigidPose coarse_pose(const TemplateDatabase& db, const TemplatePlacement& placement, const PinholeCamera& camera) {
  if (placement.view < 0 || placement.view >= static_cast<int>(db.views.size()))
    throw std::out_of_range("coarse_pose: view " + std::to_string(placement.view) + " not in the database");
  if (!(placement.scale > 0)) throw std::invalid_argument("coarse_pose: scale must be positive");
  const TemplateView& v = db.views[placement.view];
  const cv::Matx33d A = ray_alignment(camera, placement.origin_px);
  RigidPose pose;
  pose.R = A * rotation_about_z(placement.angle_rad) * v.R_m2c;
  const cv::Vec3d centre = unit_ray(camera, placement.origin_px) * (db.distance_mm / placement.scale);
  pose.t_mm = centre - pose.R * db.center_mm;
  return pose;
}

TemplatePlacement placement_of(const TemplateDatabase& db, int view, const RigidPose& pose,
                               const PinholeCamera& camera) {
  TemplatePlacement p;
  p.view = view;
  const cv::Vec3d centre = pose.R * db.center_mm + pose.t_mm;
  p.origin_px = camera.project(centre);
  p.scale = db.distance_mm / cv::norm(centre);
  const cv::Matx33d Rz = ray_alignment(camera, p.origin_px).t() * pose.R * db.views[view].R_m2c.t();
  p.angle_rad = std::atan2(Rz(1, 0), Rz(0, 0));
  return p;
}

}  // namespace mfcd::vision
