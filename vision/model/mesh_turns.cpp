#include "vision/model/mesh_turns.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>
#include <string>

namespace mfcd::vision {
namespace {

constexpr double kPi = std::numbers::pi;
// Shares closer than this are the same: a point more or less on the surface in ~1000 samples,
// where a turn's share also depends on which samples land near a feature's border.
constexpr double kShareError = 0.01;
// A near-symmetry's turn maps at least this much more than the turn by half its angle: five
// sampling errors.
constexpr double kPeakMargin = 0.05;

cv::Vec3d vec(const cv::Vec3f& v) { return {v[0], v[1], v[2]}; }

double degrees(double r) { return r * 180 / kPi; }

// Two unit vectors perpendicular to `a` and to each other.
void perpendiculars(const cv::Vec3d& a, cv::Vec3d& u, cv::Vec3d& v) {
  const cv::Vec3d helper = std::abs(a[0]) < 0.9 ? cv::Vec3d(1, 0, 0) : cv::Vec3d(0, 1, 0);
  u = cv::normalize(a.cross(helper));
  v = a.cross(u);
}

// Directions over the hemisphere z >= 0 (Fibonacci lattice): a rotation about -a is one about a.
std::vector<cv::Vec3d> hemisphere(int n) {
  std::vector<cv::Vec3d> out;
  out.reserve(static_cast<size_t>(n));
  const double golden = kPi * (3 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1 - (i + 0.5) / n;
    const double r = std::sqrt(std::max(0.0, 1 - z * z));
    out.emplace_back(r * std::cos(golden * i), r * std::sin(golden * i), z);
  }
  return out;
}

// The angle between two axes as lines (a and -a are one axis), degrees.
double axis_angle_deg(const cv::Vec3d& a, const cv::Vec3d& b) {
  return degrees(std::acos(std::min(1.0, std::abs(a.dot(b)))));
}

struct Candidate {
  cv::Vec3d axis;
  cv::Vec3d pivot;
  int order = 2;
  double share = 0;
};

// Local search over the axis direction (two tilts) and the pivot (two shifts across the axis)
// for the rotation by 2 pi / order, on `grid`, from steps `deg` and `mm` down to a tenth of them.
void refine(Candidate& c, const std::vector<cv::Vec3d>& points, const SurfaceGrid& grid, double deg, double mm) {
  const double angle = 2 * kPi / c.order;
  auto score = [&](const cv::Vec3d& axis, const cv::Vec3d& pivot) {
    return share_on_surface(points, grid, axis_rotation(axis, angle), pivot);
  };
  c.share = score(c.axis, c.pivot);
  for (double step_deg = deg, step_mm = mm; step_deg >= deg / 10; step_deg /= 2, step_mm /= 2) {
    for (bool improved = true; improved;) {
      improved = false;
      cv::Vec3d u, v;
      perpendiculars(c.axis, u, v);
      const double t = std::tan(step_deg * kPi / 180);
      const cv::Vec3d tries_axis[] = {c.axis + u * t, c.axis - u * t, c.axis + v * t, c.axis - v * t};
      for (const cv::Vec3d& a : tries_axis) {
        const cv::Vec3d n = cv::normalize(a);
        const double s = score(n, c.pivot);
        if (s > c.share) c.share = s, c.axis = n, improved = true;
      }
      const cv::Vec3d tries_pivot[] = {c.pivot + u * step_mm, c.pivot - u * step_mm, c.pivot + v * step_mm,
                                       c.pivot - v * step_mm};
      for (const cv::Vec3d& p : tries_pivot) {
        const double s = score(c.axis, p);
        if (s > c.share) c.share = s, c.pivot = p, improved = true;
      }
    }
  }
}

MeshTurn make_turn(MeshTurn::Kind kind, const cv::Vec3d& axis, const cv::Vec3d& pivot, int order, double angle,
                   double share) {
  MeshTurn t;
  t.kind = kind;
  t.axis = axis;
  t.pivot_mm = pivot;
  t.order = order;
  t.R = axis_rotation(axis, angle);
  t.on_surface = share;
  return t;
}

}  // namespace

void MeshTurnParams::validate() const {
  auto need = [](bool ok, const char* field) {
    if (!ok) throw std::invalid_argument(std::string("mesh turns: ") + field + " out of range");
  };
  need(surface_points >= 16, "surface_points");
  need(coarse_points >= 16, "coarse_points");
  need(axis_samples >= 3, "axis_samples");
  need(max_order >= 2 && max_order <= 360, "max_order");
  need(near_share > 0 && near_share < symmetry_share && symmetry_share <= 1, "near_share / symmetry_share");
  need(phase_share > 0 && phase_share < 1, "phase_share");
  need(refine_per_order >= 1, "refine_per_order");
}

cv::Matx33d axis_rotation(const cv::Vec3d& axis, double angle) {
  const cv::Vec3d a = cv::normalize(axis);
  const double c = std::cos(angle), s = std::sin(angle), k = 1 - c;
  return {c + a[0] * a[0] * k,        a[0] * a[1] * k - a[2] * s, a[0] * a[2] * k + a[1] * s,
          a[1] * a[0] * k + a[2] * s, c + a[1] * a[1] * k,        a[1] * a[2] * k - a[0] * s,
          a[2] * a[0] * k - a[1] * s, a[2] * a[1] * k + a[0] * s, c + a[2] * a[2] * k};
}

std::vector<cv::Vec3d> sample_surface(const Mesh& mesh, int count) {
  std::vector<double> cumulative;
  cumulative.reserve(mesh.triangles.size());
  double total = 0;
  for (const auto& t : mesh.triangles) {
    const cv::Vec3d a = vec(mesh.vertices[t[0]]), b = vec(mesh.vertices[t[1]]), c = vec(mesh.vertices[t[2]]);
    total += 0.5 * cv::norm((b - a).cross(c - a));
    cumulative.push_back(total);
  }
  std::vector<cv::Vec3d> out;
  if (!(total > 0) || count <= 0) return out;
  out.reserve(static_cast<size_t>(count));
  const double g1 = 0.7548776662466927, g2 = 0.5698402909980532;  // plastic-number lattice
  for (int i = 0; i < count; ++i) {
    const double at = (i + 0.5) / count * total;
    const size_t k =
        std::min(mesh.triangles.size() - 1,
                 static_cast<size_t>(std::upper_bound(cumulative.begin(), cumulative.end(), at) - cumulative.begin()));
    const auto& t = mesh.triangles[k];
    double r1 = std::fmod(0.5 + g1 * i, 1.0), r2 = std::fmod(0.5 + g2 * i, 1.0);
    if (r1 + r2 > 1) r1 = 1 - r1, r2 = 1 - r2;
    const cv::Vec3d a = vec(mesh.vertices[t[0]]), b = vec(mesh.vertices[t[1]]), c = vec(mesh.vertices[t[2]]);
    out.push_back(a + (b - a) * r1 + (c - a) * r2);
  }
  return out;
}

double share_on_surface(const std::vector<cv::Vec3d>& points, const SurfaceGrid& surface, const cv::Matx33d& R,
                        const cv::Vec3d& pivot) {
  if (points.empty()) return 0;
  size_t on = 0;
  for (const cv::Vec3d& p : points) on += surface.near(R * (p - pivot) + pivot);
  return double(on) / double(points.size());
}

namespace {

// Per order, the best distinct axes of the coarse scan, refined down to the fine grid; those that
// still map at least params.near_share.
std::vector<Candidate> scan_axes(const Mesh& mesh, const SurfaceGrid& fine, const MeshTurnParams& params,
                                 const std::vector<cv::Vec3d>& points, const MeshTurns& frame) {
  const std::vector<cv::Vec3d> coarse_points = sample_surface(mesh, params.coarse_points);
  const cv::Vec3d c = frame.centroid_mm;
  // Grids of the part's size for the scan and the first refinement: a turn by a few degrees off
  // the true axis still maps the surface within their tolerance.
  const double size = cv::norm(vec(mesh.bbox_max()) - vec(mesh.bbox_min()));
  const SurfaceGrid coarse(mesh, size / 100, size / 40);
  const SurfaceGrid medium(mesh, size / 250, size / 100);

  std::vector<cv::Vec3d> axes = hemisphere(params.axis_samples);
  for (int r = 0; r < 3; ++r)
    axes.emplace_back(frame.principal_axes(r, 0), frame.principal_axes(r, 1), frame.principal_axes(r, 2));

  std::vector<Candidate> found;
  std::vector<std::pair<double, size_t>> scored;
  for (int n = 2; n <= params.max_order; ++n) {
    scored.clear();
    for (size_t i = 0; i < axes.size(); ++i)
      scored.emplace_back(share_on_surface(coarse_points, coarse, axis_rotation(axes[i], 2 * kPi / n), c), i);
    std::sort(scored.begin(), scored.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
    std::vector<Candidate> kept;
    for (const auto& [share, i] : scored) {
      if (share < params.near_share || static_cast<int>(kept.size()) >= params.refine_per_order) break;
      const cv::Vec3d& axis = axes[i];  // clang 14 cannot capture a structured binding
      if (std::any_of(kept.begin(), kept.end(), [&](const Candidate& k) { return axis_angle_deg(k.axis, axis) < 10; }))
        continue;
      Candidate cand{axes[i], c, n, share};
      refine(cand, coarse_points, coarse, 3, size / 100);
      refine(cand, points, medium, 1, size / 400);
      refine(cand, points, fine, 0.3, fine.tolerance_mm() / 2);
      kept.push_back(cand);
    }
    for (const Candidate& k : kept)
      if (k.share >= params.near_share) found.push_back(k);
  }
  return found;
}

// One axis of the part and the orders of the turns about it that the scan found.
struct Axis {
  cv::Vec3d axis, pivot;
  int lowest = 0;
  std::vector<std::pair<int, double>> orders;  // (order, fine share; 0: no repetition)
};

// Per distinct axis (within 10 degrees: a small turn about an axis a few degrees off still maps
// a part onto itself), the axis and pivot refined for its lowest order (the largest turn, which
// a tilted axis spoils most) and every order scored again about them.
std::vector<Axis> group_by_axis(const std::vector<Candidate>& found, const std::vector<cv::Vec3d>& points,
                                const SurfaceGrid& fine, const MeshTurnParams& params) {
  std::vector<Axis> lines;
  for (const Candidate& f : found) {
    auto it =
        std::find_if(lines.begin(), lines.end(), [&](const Axis& a) { return axis_angle_deg(a.axis, f.axis) < 10; });
    if (it == lines.end()) {
      lines.push_back({f.axis, f.pivot, f.order, {}});
      it = lines.end() - 1;
    } else if (f.order < it->lowest) {
      it->axis = f.axis, it->pivot = f.pivot, it->lowest = f.order;
    }
    it->orders.emplace_back(f.order, 0);
  }
  // A near-symmetry repeats: its turn maps more of the part than the turn by half its angle (a
  // gear's tooth period, not half a tooth). A flat part turned a little about its normal keeps most
  // of its faces on themselves at every small angle, and that is no repetition.
  for (Axis& line : lines) {
    std::sort(line.orders.begin(), line.orders.end());
    line.orders.erase(std::unique(line.orders.begin(), line.orders.end()), line.orders.end());
    for (auto& [n, share] : line.orders) {
      share = share_on_surface(points, fine, axis_rotation(line.axis, 2 * kPi / n), line.pivot);
      if (share >= params.symmetry_share) continue;
      const double valley = share_on_surface(points, fine, axis_rotation(line.axis, kPi / n), line.pivot);
      if (share < valley + kPeakMargin) share = 0;
    }
  }
  return lines;
}

// The symmetry of one axis (into out.symmetries, its discrete turns into `symmetric`), its
// near-symmetric turns and its phase turns (into out.alternatives).
void classify_axis(const Axis& line, const MeshTurnParams& params, MeshTurns& out,
                   std::vector<cv::Matx33d>& symmetric) {
  int exact = 1, near = 1, exact_orders = 0;
  double near_share = 0;
  for (const auto& [n, s] : line.orders)
    if (s >= params.symmetry_share) exact = std::max(exact, n), ++exact_orders;
  // The near order that maps the most, the highest of those within a sampling error of it (a
  // gear's tooth count: its divisors map as much, half a tooth less).
  auto near_order = [&](int n, double s) {
    return s >= params.near_share && s < params.symmetry_share && exact % n != 0 && n % exact == 0;
  };
  for (const auto& [n, s] : line.orders)
    if (near_order(n, s)) near_share = std::max(near_share, s);
  for (const auto& [n, s] : line.orders)
    if (near_order(n, s) && s >= near_share - kShareError) near = std::max(near, n);
  const bool continuous = exact_orders == params.max_order - 1;
  if (exact > 1) {
    out.symmetries.push_back(make_turn(MeshTurn::Kind::symmetry, line.axis, line.pivot, continuous ? 0 : exact,
                                       continuous ? 0 : 2 * kPi / exact, 1));
    if (!continuous)
      for (int k = 1; k < exact; ++k) symmetric.push_back(axis_rotation(line.axis, 2 * kPi * k / exact));
  }
  // Every turn by a multiple of the near period that is not a symmetry is its own twin.
  for (int k = 1; k < near; ++k)
    if ((k * exact) % near != 0)
      out.alternatives.push_back(
          make_turn(MeshTurn::Kind::near_symmetry, line.axis, line.pivot, near, 2 * kPi * k / near, near_share));
  // Phase turns by the period of the repeated features: the symmetry's, else the near one's.
  const int period = exact >= 3 ? exact : near;
  if (!continuous && period >= 3)
    for (const double sign : {1.0, -1.0})
      out.alternatives.push_back(make_turn(MeshTurn::Kind::phase, line.axis, line.pivot, period,
                                           sign * params.phase_share * 2 * kPi / period, 0));
}

// Turns over: 180 degrees about each principal axis, unless that is a symmetry or already a
// near-symmetry, and one per class modulo the symmetries found.
void add_turns_over(const std::vector<cv::Vec3d>& points, const SurfaceGrid& fine, const MeshTurnParams& params,
                    std::vector<cv::Matx33d> symmetric, MeshTurns& out) {
  for (const MeshTurn& s : out.symmetries)
    if (s.order == 0) symmetric.clear();  // continuous: handled by the axis test below
  auto same_class = [&](const cv::Matx33d& a, const cv::Matx33d& b) {
    auto close = [](const cv::Matx33d& x, const cv::Matx33d& y) { return cv::norm(x - y, cv::NORM_INF) < 0.05; };
    if (close(a, b)) return true;
    for (const cv::Matx33d& S : symmetric)
      if (close(a, b * S)) return true;
    return false;
  };
  for (int r = 0; r < 3; ++r) {
    const cv::Vec3d axis(out.principal_axes(r, 0), out.principal_axes(r, 1), out.principal_axes(r, 2));
    const cv::Matx33d R = axis_rotation(axis, kPi);
    // A symmetry itself: in the class of no turn at all.
    bool skip = same_class(R, cv::Matx33d::eye());
    for (const MeshTurn& s : out.symmetries) {
      // A half turn about a continuous or even-order symmetry axis is a symmetry; about any axis
      // perpendicular to a continuous one, all such turns are one class.
      if (axis_angle_deg(s.axis, axis) < 3 && (s.order == 0 || s.order % 2 == 0)) skip = true;
      if (s.order == 0 && axis_angle_deg(s.axis, axis) > 87 &&
          std::any_of(out.alternatives.begin(), out.alternatives.end(), [&](const MeshTurn& t) {
            return t.kind == MeshTurn::Kind::turn_over && axis_angle_deg(t.axis, s.axis) > 87;
          }))
        skip = true;
    }
    for (const MeshTurn& t : out.alternatives)
      if (t.kind != MeshTurn::Kind::phase && same_class(t.R, R)) skip = true;
    if (skip) continue;
    const double share = share_on_surface(points, fine, R, out.centroid_mm);
    if (share >= params.symmetry_share) continue;
    out.alternatives.push_back(make_turn(MeshTurn::Kind::turn_over, axis, out.centroid_mm, 2, kPi, share));
  }
}

}  // namespace

MeshTurns find_mesh_turns(const Mesh& mesh, const SurfaceGrid& fine, const MeshTurnParams& params) {
  params.validate();
  if (mesh.vertices.empty() || mesh.triangles.empty()) throw std::invalid_argument("mesh turns: empty mesh");
  MeshTurns out;
  const std::vector<cv::Vec3d> points = sample_surface(mesh, params.surface_points);
  if (points.empty()) throw std::invalid_argument("mesh turns: the mesh has no area");

  // Centroid and principal axes of the surface samples.
  cv::Vec3d c(0, 0, 0);
  for (const cv::Vec3d& p : points) c += p;
  c *= 1.0 / double(points.size());
  cv::Matx33d cov = cv::Matx33d::zeros();
  for (const cv::Vec3d& p : points) cov += (p - c) * (p - c).t();
  cv::Mat values, vectors;
  cv::eigen(cv::Mat(cov), values, vectors);  // descending; rows are eigenvectors
  out.centroid_mm = c;
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) out.principal_axes(r, k) = vectors.at<double>(r, k);
  // A right-handed frame (a rotation): an axis's sign says nothing about the part.
  if (cv::determinant(out.principal_axes) < 0)
    for (int k = 0; k < 3; ++k) out.principal_axes(2, k) = -out.principal_axes(2, k);

  std::vector<cv::Matx33d> symmetric;  // every discrete rotation found to be a symmetry
  for (const Axis& line : group_by_axis(scan_axes(mesh, fine, params, points, out), points, fine, params))
    classify_axis(line, params, out, symmetric);
  add_turns_over(points, fine, params, std::move(symmetric), out);
  return out;
}

std::string describe(const MeshTurns& turns) {
  std::string out = "symmetry ";
  if (turns.symmetries.empty()) out += "none";
  for (size_t i = 0; i < turns.symmetries.size(); ++i) {
    const int n = turns.symmetries[i].order;
    out += (i ? ", " : "") + (n == 0 ? std::string("continuous") : std::to_string(n) + "-fold");
  }
  int over = 0, near = 0, phase = 0, near_order = 0;
  double near_share = 1;
  for (const MeshTurn& t : turns.alternatives) {
    if (t.kind == MeshTurn::Kind::turn_over) ++over;
    if (t.kind == MeshTurn::Kind::phase) ++phase;
    if (t.kind == MeshTurn::Kind::near_symmetry)
      ++near, near_order = std::max(near_order, t.order), near_share = std::min(near_share, t.on_surface);
  }
  out += "; checked: " + std::to_string(over) + " turned over";
  if (near > 0) {
    char share[16];
    std::snprintf(share, sizeof share, "%.2f", near_share);
    out += ", " + std::to_string(near) + " near-symmetric (up to " + std::to_string(near_order) + "-fold, " + share +
           " on the surface)";
  }
  if (phase > 0) out += ", " + std::to_string(phase) + " phase";
  return out;
}

SurfaceGrid turn_surface(const Mesh& mesh, double diameter_mm) {
  const double tolerance = std::clamp(0.002 * diameter_mm, 0.1, 0.5);
  const cv::Vec3f size = mesh.bbox_max() - mesh.bbox_min();
  const double volume = (size[0] + 2 * tolerance) * (size[1] + 2 * tolerance) * (size[2] + 2 * tolerance);
  return SurfaceGrid(mesh, std::max(tolerance / 2, std::cbrt(volume / 64e6)), tolerance);
}

MeshTurns find_part_turns(const Mesh& mesh, double diameter_mm, const MeshTurnParams& params) {
  return find_mesh_turns(mesh, turn_surface(mesh, diameter_mm), params);
}

}  // namespace mfcd::vision
