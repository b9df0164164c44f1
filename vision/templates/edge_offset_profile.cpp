#include "vision/templates/edge_offset_profile.hpp"

#include "vision/common/rotation.hpp"
#include "vision/edges/depth_edges.hpp"
#include "vision/model/mesh.hpp"
#include "vision/render/mfc_renderer.hpp"
#include "vision/templates/render_window.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace mfcd::vision {

double EdgeOffsetProfile::at(double normal_angle) const {
  if (offset_px.empty()) return 0;
  const int n = static_cast<int>(offset_px.size());
  double f = normal_angle / (2 * std::numbers::pi) * n;
  f -= n * std::floor(f / n);  // [0, n)
  const int i = std::min(static_cast<int>(f), n - 1);
  const double w = f - i;
  return offset_px[i] * (1 - w) + offset_px[(i + 1) % n] * w;
}

double EdgeOffsetProfile::mean_near(double centre_deg, double half_width_deg) const {
  double sum = 0;
  int n = 0;
  for (size_t k = 0; k < offset_px.size(); ++k) {
    double d = std::fmod(360.0 / offset_px.size() * k - centre_deg, 90.0);
    if (d < 0) d += 90;
    if (std::min(d, 90 - d) <= half_width_deg) sum += offset_px[k], ++n;
  }
  return n > 0 ? sum / n : 0;
}

EdgeOffsetProfile measure_edge_offset_profile(const CameraConfig& camera, double distance_mm,
                                              const EdgeProfileConditions& conditions,
                                              const DepthEdgeParams& edge_params) {
  if (!(distance_mm > 50)) throw std::invalid_argument("edge offset profile: distance must be > 50 mm");
  if (conditions.turns < 4) throw std::invalid_argument("edge offset profile: at least 4 turns");
  constexpr double kSide = 40, kHeight = 6;
  const PinholeCamera& cam = camera.camera;
  const double f = std::max(cam.fx(), cam.fy());
  // Window around the principal point holding the turned plate, its sub-pixel shifts and the
  // widest shadow on the floor (as the teacher's view windows): ~5x fewer pixels than the image.
  const double floor_z = distance_mm + kHeight + conditions.floor_gap_mm;
  const int half = window_half_px(camera, f * (kSide / std::numbers::sqrt2 + 3) / distance_mm, distance_mm, floor_z);
  const PinholeCamera view = cam.cropped(window_on_axis(cam, half));

  RenderOptions options;
  options.noise.enabled = conditions.noise;
  options.deferred_shading = true;  // as the views are rendered
  MfcRenderer renderer(camera, options);
  renderer.set_camera(view);
  const int plate = renderer.add_mesh(make_box(kSide, kSide, kHeight));
  const int floor = renderer.add_mesh(make_plane(8 * kSide));
  DepthEdgeExtractor extractor(view, camera.flashes, edge_params);
  MfcRender render;
  DepthEdges edges;

  const int bins = EdgeOffsetProfile::kBins;
  std::vector<double> sum(bins, 0);
  std::vector<int> count(bins, 0);
  // Model z turned towards the camera: the top face (z = +h/2) faces it.
  const cv::Matx33d face_camera(1, 0, 0, 0, -1, 0, 0, 0, -1);
  for (int k = 0; k < conditions.turns; ++k) {
    const double turn = (k + 0.37) * (std::numbers::pi / 2) / conditions.turns;
    const cv::Matx33d R = rotation_about_z(turn) * face_camera;
    // Fractions of a pixel (1 mm ~ f / distance px) so that the outline crosses the pixel grid at
    // every phase, not only where one position puts it.
    const cv::Vec3d t(0.37 * (k % 7) - 1.1, -0.29 * (k % 5) + 0.6, distance_mm + kHeight / 2);
    const ScenePart parts[2] = {{plate, R, t, Material::matte(0.6f)},
                                {floor, cv::Matx33d::eye(), cv::Vec3d(0, 0, floor_z), Material::matte(0.5f)}};
    renderer.render(parts, render, 1000 + static_cast<uint64_t>(k));
    extractor.extract(render.frames, edges);

    cv::Point2d corner[4];
    const double xs[4] = {-kSide / 2, kSide / 2, kSide / 2, -kSide / 2};
    const double ys[4] = {-kSide / 2, -kSide / 2, kSide / 2, kSide / 2};
    cv::Point2d centre(0, 0);
    for (int i = 0; i < 4; ++i) {
      corner[i] = view.project(R * cv::Vec3d(xs[i], ys[i], kHeight / 2) + t);
      centre += corner[i] * 0.25;
    }
    for (int s = 0; s < 4; ++s) {
      const cv::Point2d a = corner[s], b = corner[(s + 1) % 4];
      const double length = cv::norm(b - a);
      const cv::Point2d along = (b - a) * (1.0 / length);
      cv::Point2d out(-along.y, along.x);
      if ((a - centre).dot(out) < 0) out = -out;  // the floor, i.e. the shadow, is outside
      double angle = std::atan2(out.y, out.x);
      if (angle < 0) angle += 2 * std::numbers::pi;
      const int bin = static_cast<int>(std::lround(angle / (2 * std::numbers::pi) * bins)) % bins;
      for (int y = 0; y < edges.edges.rows; ++y)
        for (int x = 0; x < edges.edges.cols; ++x) {
          if (!edges.edges(y, x)) continue;
          const cv::Point2d q = cv::Point2d(x, y) - a;
          const double u = q.dot(along), off = q.dot(out);
          if (u < 8 || u > length - 8 || std::abs(off) > 2.5) continue;
          sum[bin] += off;
          ++count[bin];
        }
    }
  }
  EdgeOffsetProfile profile;
  profile.offset_px.resize(bins);
  for (int b = 0; b < bins; ++b) {
    if (count[b] < 50)
      throw std::runtime_error("edge offset profile: " + std::to_string(count[b]) + " edge pixels at " +
                               std::to_string(5 * b) + " degrees (the plate's outline was not found)");
    profile.offset_px[b] = static_cast<float>(sum[b] / count[b]);
  }
  return profile;
}

}  // namespace mfcd::vision
