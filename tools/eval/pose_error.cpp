#include "tools/eval/pose_error.hpp"

#include "tools/common/cli_numbers.hpp"
#include "vision/pose/rigid_transform.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>

namespace mfcd::eval {

namespace {

// The whole text as an integer (tools::parse_int's rule), or nothing.
std::optional<int> whole_number(const std::string& text) {
  try {
    return tools::parse_int("", text);
  } catch (const std::invalid_argument&) {
    return std::nullopt;
  }
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t\r");
  return s.substr(b, e - b + 1);
}

// The rows of a comma-separated table ('#' comments, blank lines skipped, fields trimmed): `row`
// gets each row's fields and "FILE:LINE: " for its errors. `what` names the table when the file
// cannot be opened.
template <class Row>
void for_each_csv_row(const std::filesystem::path& file, const char* what, Row row) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error(file.string() + ": cannot open the " + what);
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    line = trim(line);
    if (line.empty()) continue;
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string x; std::getline(ss, x, ',');) f.push_back(trim(x));
    row(file.string() + ":" + std::to_string(number) + ": ", f);
  }
}

}  // namespace

std::vector<PartEntry> read_parts_csv(const std::filesystem::path& file) {
  std::vector<PartEntry> parts;
  bool header = false;
  for_each_csv_row(file, "parts table", [&](const std::string& where, const std::vector<std::string>& f) {
    if (f.size() < 3 || f.size() > 5)
      throw std::runtime_error(where + "expected 3 to 5 fields name,obj_id,symmetry[,views_symmetry[,views]], got " +
                               std::to_string(f.size()));
    if (!header && f[0] == "name") {
      header = true;
      return;
    }
    PartEntry p;
    p.name = f[0];
    if (p.name.empty()) throw std::runtime_error(where + "empty part name");
    const std::optional<int> obj_id = whole_number(f[1]);
    if (!obj_id || *obj_id < 1) throw std::runtime_error(where + "obj_id '" + f[1] + "' is not a positive integer");
    p.obj_id = *obj_id;
    try {
      p.symmetry = vision::PartSymmetry::parse(f[2]);
    } catch (const std::exception& e) {
      throw std::runtime_error(where + "symmetry '" + f[2] + "': " + e.what());
    }
    p.views_symmetry = p.symmetry;
    if (f.size() >= 4) {
      try {
        p.views_symmetry = vision::PartSymmetry::parse(f[3]);
      } catch (const std::exception& e) {
        throw std::runtime_error(where + "views_symmetry '" + f[3] + "': " + e.what());
      }
      if (!p.symmetry.includes(p.views_symmetry))
        throw std::runtime_error(where + "views_symmetry " + f[3] + " is not a symmetry of the part (" + f[2] + ")");
    }
    if (f.size() == 5) {
      const std::optional<int> views = whole_number(f[4]);
      if (!views || *views < 1 || *views > 100000)
        throw std::runtime_error(where + "views '" + f[4] + "' is not an integer in 1..100000");
      p.views = *views;
    }
    for (const auto& q : parts) {
      if (q.name == p.name) throw std::runtime_error(where + "part '" + p.name + "' listed twice");
      if (q.obj_id == p.obj_id)
        throw std::runtime_error(where + "obj_id " + f[1] + " used by '" + q.name + "' and '" + p.name + "'");
    }
    parts.push_back(std::move(p));
  });
  if (parts.empty()) throw std::runtime_error(file.string() + ": no parts listed");
  return parts;
}

std::vector<std::pair<int, vision::GraspFeature>> read_grasp_features_csv(const std::filesystem::path& file,
                                                                          const std::vector<PartEntry>& parts) {
  std::vector<std::pair<int, vision::GraspFeature>> features;
  bool header = false;
  for_each_csv_row(file, "grasp features table", [&](const std::string& where, const std::vector<std::string>& f) {
    if (f.size() != 10)
      throw std::runtime_error(where +
                               "expected 10 fields name,obj_id,x_mm,y_mm,z_mm,radius_mm,approach_x,"
                               "approach_y,approach_z,max_tilt_deg, got " +
                               std::to_string(f.size()));
    if (!header && f[0] == "name") {
      header = true;
      return;
    }
    const std::optional<int> obj_id = whole_number(f[1]);
    if (!obj_id) throw std::runtime_error(where + "obj_id '" + f[1] + "' is not an integer");
    const PartEntry& part = part_by_id(parts, *obj_id, where.substr(0, where.size() - 2));
    if (part.name != f[0])
      throw std::runtime_error(where + "obj_id " + f[1] + " is '" + part.name + "' in the parts table, not '" + f[0] +
                               "'");
    double v[8];
    static const char* const names[8] = {"x_mm",       "y_mm",       "z_mm",       "radius_mm",
                                         "approach_x", "approach_y", "approach_z", "max_tilt_deg"};
    for (int i = 0; i < 8; ++i) {
      try {
        v[i] = tools::parse_double(names[i], f[static_cast<size_t>(i) + 2]);
      } catch (const std::invalid_argument&) {
        throw std::runtime_error(where + names[i] + " '" + f[static_cast<size_t>(i) + 2] + "' is not a number");
      }
    }
    vision::GraspFeature g;
    g.point_mm = {v[0], v[1], v[2]};
    g.radius_mm = v[3];
    g.approach = {v[4], v[5], v[6]};
    g.max_tilt_deg = v[7];
    if (const std::string why = g.validate(); !why.empty()) throw std::runtime_error(where + why);
    features.emplace_back(*obj_id, g);
  });
  if (features.empty()) throw std::runtime_error(file.string() + ": no grasp features listed");
  return features;
}

double true_grasp_visibility(const vision::GraspFeature& feature, const cv::Matx33d& R, const cv::Vec3d& t_mm,
                             const vision::PinholeCamera& camera, const cv::Mat1b& mask, const cv::Mat1b& mask_visib) {
  CV_Assert(mask.size() == mask_visib.size());
  if (!vision::grasp_faces_camera(feature, vision::RigidPose{R, t_mm})) return 0;
  const cv::Vec3d g = R * feature.point_mm + t_mm;
  if (g[2] <= 0) return 0;
  const cv::Point2d c = camera.project(g);
  const double r = feature.radius_mm * camera.fx() / g[2];
  int disc = 0, on_part = 0, visible = 0;
  for (int y = static_cast<int>(std::floor(c.y - r)); y <= static_cast<int>(std::ceil(c.y + r)); ++y)
    for (int x = static_cast<int>(std::floor(c.x - r)); x <= static_cast<int>(std::ceil(c.x + r)); ++x) {
      if ((x - c.x) * (x - c.x) + (y - c.y) * (y - c.y) > r * r) continue;
      ++disc;  // pixels outside the image count as part of the disc, never as seen
      if (x < 0 || y < 0 || x >= mask.cols || y >= mask.rows || !mask(y, x)) continue;
      ++on_part;
      visible += mask_visib(y, x) != 0;
    }
  if (disc == 0 || on_part * 5 < disc) return 0;
  return static_cast<double>(visible) / on_part;
}

const PartEntry& part_by_id(const std::vector<PartEntry>& parts, int obj_id, const std::string& source) {
  for (const auto& p : parts)
    if (p.obj_id == obj_id) return p;
  throw std::runtime_error(source + ": unknown part: obj_id " + std::to_string(obj_id) + " is not in the parts table");
}

double rotation_angle_deg(const cv::Matx33d& R) {
  // atan2 of |axis * sin| and cos: accurate at both ends, unlike acos of the trace.
  const double c = (cv::trace(R) - 1) / 2;
  const cv::Vec3d v(R(2, 1) - R(1, 2), R(0, 2) - R(2, 0), R(1, 0) - R(0, 1));
  return std::atan2(cv::norm(v) / 2, c) * 180 / CV_PI;
}

cv::Vec3d euler_xyz_deg(const cv::Matx33d& R) {
  const double y = std::asin(std::clamp(-R(2, 0), -1.0, 1.0));
  const double x = std::atan2(R(2, 1), R(2, 2));
  const double z = std::atan2(R(1, 0), R(0, 0));
  return cv::Vec3d(x, y, z) * (180 / CV_PI);
}

namespace {

// Unit axis of a rotation (0 for none). From the skew part where it is well conditioned; near a
// half turn, where the skew part vanishes, from the symmetric part (R + R^T) / 2 = cos(angle) I +
// (1 - cos(angle)) a a^T (a a^T's largest column), signed by what is left of the skew part.
cv::Vec3d rotation_axis(const cv::Matx33d& R) {
  const cv::Vec3d v(R(2, 1) - R(1, 2), R(0, 2) - R(2, 0), R(1, 0) - R(0, 1));
  const double angle = rotation_angle_deg(R);
  if (angle < 1e-9) return {0, 0, 0};
  if (angle < 170) return v / cv::norm(v);
  const double c = std::cos(angle * CV_PI / 180);
  const cv::Matx33d B = ((R + R.t()) * 0.5 - cv::Matx33d::eye() * c) * (1 / (1 - c));  // = a a^T
  int k = 0;
  for (int i = 1; i < 3; ++i)
    if (B(i, i) > B(k, k)) k = i;
  cv::Vec3d a(B(0, k), B(1, k), B(2, k));
  a /= cv::norm(a);
  return a.dot(v) < 0 ? -a : a;
}

// Errors of an estimate against one equivalent of the ground truth.
PoseError error_against(const cv::Matx33d& R_est, const cv::Vec3d& t_est, const cv::Matx33d& R_eq,
                        const cv::Vec3d& t_eq, const cv::Vec3d& centre_mm) {
  PoseError e;
  const cv::Matx33d rel = R_est * R_eq.t();
  e.rotation_deg = rotation_angle_deg(rel);
  const cv::Vec3d c_est = R_est * centre_mm + t_est, c_gt = R_eq * centre_mm + t_eq;
  const cv::Vec3d d = c_est - c_gt;
  e.position_mm = cv::norm(d);
  e.d_t_mm = d;
  e.abs_t_mm = {std::abs(d[0]), std::abs(d[1]), std::abs(d[2])};
  const cv::Vec3d r = euler_xyz_deg(rel);
  e.abs_r_deg = {std::abs(r[0]), std::abs(r[1]), std::abs(r[2])};
  e.axis_cam = rotation_axis(rel);
  return e;
}

cv::Matx33d rotation_of(const cv::Matx44d& T) {
  return cv::Matx33d(T(0, 0), T(0, 1), T(0, 2), T(1, 0), T(1, 1), T(1, 2), T(2, 0), T(2, 1), T(2, 2));
}

}  // namespace

PoseError pose_error(const cv::Matx33d& R_est, const cv::Vec3d& t_est, const cv::Matx33d& R_gt, const cv::Vec3d& t_gt,
                     const vision::PartSymmetry& symmetry, const cv::Vec3d& centre_mm) {
  // The ground-truth equivalent closest to the estimate.
  cv::Matx33d best = R_gt;
  if (symmetry.kind == vision::PartSymmetry::Kind::continuous_z) {
    // max over a of trace(R_est^T R_gt Rz(a)) = (A00 + A11) cos a + (A01 - A10) sin a + A22.
    const cv::Matx33d A = R_est.t() * R_gt;
    best = R_gt * vision::rotation_about_z(std::atan2(A(0, 1) - A(1, 0), A(0, 0) + A(1, 1)));
  } else {
    double best_angle = 1e9;
    for (const auto& S : symmetry.discrete_rotations()) {
      const double a = rotation_angle_deg(R_est * (R_gt * S).t());
      if (a < best_angle) best_angle = a, best = R_gt * S;
    }
  }
  return error_against(R_est, t_est, best, t_gt, centre_mm);
}

PoseError pose_error(const cv::Matx33d& R_est, const cv::Vec3d& t_est, const cv::Matx33d& R_gt, const cv::Vec3d& t_gt,
                     const std::vector<cv::Matx44d>& symmetries, const cv::Vec3d& centre_mm) {
  CV_Assert(!symmetries.empty());
  double best_angle = 1e9;
  cv::Matx33d best_R = R_gt;
  cv::Vec3d best_t = t_gt;
  for (const auto& S : symmetries) {
    const cv::Matx33d R_eq = R_gt * rotation_of(S);
    const double a = rotation_angle_deg(R_est * R_eq.t());
    if (a < best_angle) best_angle = a, best_R = R_eq, best_t = R_gt * cv::Vec3d(S(0, 3), S(1, 3), S(2, 3)) + t_gt;
  }
  return error_against(R_est, t_est, best_R, best_t, centre_mm);
}

std::vector<cv::Matx44d> symmetry_transforms(const vision::BopModelInfo& info, double continuous_step_deg) {
  CV_Assert(continuous_step_deg > 0 && continuous_step_deg <= 360);
  std::vector<cv::Matx44d> discrete{cv::Matx44d::eye()};
  discrete.insert(discrete.end(), info.symmetries_discrete.begin(), info.symmetries_discrete.end());
  std::vector<cv::Matx44d> continuous{cv::Matx44d::eye()};
  for (const auto& c : info.symmetries_continuous) {
    const cv::Vec3d axis = c.axis / cv::norm(c.axis);
    const int steps = std::max(1, static_cast<int>(std::lround(360.0 / continuous_step_deg)));
    for (int k = 1; k < steps; ++k) {
      const cv::Matx33d R = vision::rotation_from_angle_axis(axis * (2 * CV_PI * k / steps));
      // A turn about the axis through `offset`: p -> R (p - o) + o.
      const cv::Vec3d t = c.offset - R * c.offset;
      continuous.push_back(cv::Matx44d(R(0, 0), R(0, 1), R(0, 2), t[0], R(1, 0), R(1, 1), R(1, 2), t[1], R(2, 0),
                                       R(2, 1), R(2, 2), t[2], 0, 0, 0, 1));
    }
  }
  std::vector<cv::Matx44d> out;
  for (const auto& C : continuous)
    for (const auto& D : discrete) out.push_back(C * D);
  return out;
}

}  // namespace mfcd::eval
