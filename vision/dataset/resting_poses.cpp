#include "vision/dataset/resting_poses.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace mfcd::vision {

cv::Vec3d centre_of_mass(const Mesh& mesh) {
  double volume = 0;
  cv::Vec3d moment(0, 0, 0);
  for (const auto& t : mesh.triangles) {
    const cv::Vec3d a = mesh.vertices[t[0]], b = mesh.vertices[t[1]], c = mesh.vertices[t[2]];
    const double v = a.dot(b.cross(c)) / 6.0;  // signed volume of the tetrahedron (0, a, b, c)
    volume += v;
    moment += v * (a + b + c) / 4.0;
  }
  cv::Vec3d mean(0, 0, 0);
  for (const auto& v : mesh.vertices) mean += cv::Vec3d(v);
  if (!mesh.vertices.empty()) mean /= static_cast<double>(mesh.vertices.size());
  // A closed mesh of a 30 mm part has |volume| in the thousands of mm^3; near zero means
  // the mesh is open or flat, and the signed sums mean nothing.
  if (std::abs(volume) < 1e-6 * std::pow(cv::norm(mesh.bbox_max() - mesh.bbox_min()), 3)) return mean;
  return moment / volume;
}

namespace {

// Solid angle of the triangle (a, b, c), given relative to the viewpoint (Van Oosterom and
// Strackee's formula); unsigned.
double triangle_solid_angle(const cv::Vec3d& a, const cv::Vec3d& b, const cv::Vec3d& c) {
  const double la = cv::norm(a), lb = cv::norm(b), lc = cv::norm(c);
  const double numerator = std::abs(a.dot(b.cross(c)));
  const double denominator = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
  return 2.0 * std::atan2(numerator, denominator);
}

}  // namespace

std::vector<RestingPose> stable_resting_poses(const Mesh& mesh, double min_margin_mm) {
  const cv::Vec3d com = centre_of_mass(mesh);
  const double size = cv::norm(mesh.bbox_max() - mesh.bbox_min());
  const double plane_tol = 1e-4 * size + 1e-3;  // STL coordinates are single precision
  std::vector<cv::Vec3d> tried;
  std::vector<RestingPose> poses;
  for (const auto& t : mesh.triangles) {
    const cv::Vec3d a = mesh.vertices[t[0]], b = mesh.vertices[t[1]], c = mesh.vertices[t[2]];
    cv::Vec3d n = (b - a).cross(c - a);
    const double len = cv::norm(n);
    if (len < 1e-9) continue;
    n /= len;
    if (std::any_of(tried.begin(), tried.end(), [&](const cv::Vec3d& m) { return m.dot(n) > 1 - 1e-9; })) continue;
    tried.push_back(n);
    double h = -1e300;
    for (const auto& v : mesh.vertices) h = std::max(h, cv::Vec3d(v).dot(n));
    if (a.dot(n) < h - plane_tol) continue;  // some vertex lies beyond this triangle's plane
    // Orthonormal basis (u, w, n), right-handed: u x w = n.
    const cv::Vec3d helper = std::abs(n[0]) < 0.9 ? cv::Vec3d(1, 0, 0) : cv::Vec3d(0, 1, 0);
    const cv::Vec3d u = cv::normalize(helper - helper.dot(n) * n);
    const cv::Vec3d w = n.cross(u);
    std::vector<cv::Point2f> contact;
    for (const auto& v : mesh.vertices)
      if (cv::Vec3d(v).dot(n) >= h - plane_tol)
        contact.emplace_back(static_cast<float>(cv::Vec3d(v).dot(u)), static_cast<float>(cv::Vec3d(v).dot(w)));
    if (contact.size() < 3) continue;
    std::vector<cv::Point2f> hull;
    cv::convexHull(contact, hull);
    const double area = cv::contourArea(hull);
    if (area < 1.0) continue;  // an edge or a sliver: the part would tip over
    const cv::Point2f p(static_cast<float>(com.dot(u)), static_cast<float>(com.dot(w)));
    const double margin = cv::pointPolygonTest(hull, p, true);
    if (margin < min_margin_mm) continue;
    RestingPose pose;
    pose.R = cv::Matx33d(u[0], u[1], u[2], w[0], w[1], w[2], n[0], n[1], n[2]);
    pose.face_normal = n;
    pose.support_area_mm2 = area;
    pose.com_margin_mm = margin;
    // The support polygon is convex and the centre of mass lies off its plane, so a fan of
    // triangles from one vertex covers it without overlap.
    auto corner = [&](const cv::Point2f& q) { return u * double(q.x) + w * double(q.y) + n * h - com; };
    for (size_t k = 1; k + 1 < hull.size(); ++k)
      pose.solid_angle_sr += triangle_solid_angle(corner(hull[0]), corner(hull[k]), corner(hull[k + 1]));
    poses.push_back(pose);
  }
  std::sort(poses.begin(), poses.end(),
            [](const RestingPose& x, const RestingPose& y) { return x.support_area_mm2 > y.support_area_mm2; });
  return poses;
}

}  // namespace mfcd::vision
