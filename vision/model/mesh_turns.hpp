#pragma once
// The turns of a part that its edges may not tell apart, found from the mesh alone: no symmetry
// declared by the user, no axis assumed to be a model axis.
//
// A turn is a rotation of the part about a point (its pivot). Three kinds matter to a pose
// estimate from one view of edges:
// - a symmetry: the turn maps (all but a sliver of) the surface onto itself; the turned pose is
//   the same placed part, nothing to tell apart;
// - a near-symmetry: the turn maps most of the surface onto itself, but a feature (a keyway in a
//   gear's hub, a toggle on a housing, a chamfer on one side) lands in air; only that feature's
//   edges can tell the pose from its turned twin;
// - a turn over: 180 degrees about a principal axis of the surface that is not a symmetry. The
//   outline of a part seen along an axis is nearly that of the part turned over about a
//   perpendicular one (a mirror image), so a fit can settle on either.
// For a rotational symmetry or near-symmetry of order N >= 3 about an axis, a fit can also settle
// with every repeated feature's flank on its neighbour's opposite flank, about half a period off:
// phase turns of +-0.4 of the period start a fit in the other basin.
//
// How they are found: rotations by 360/N degrees (N = 2..max_order) about axes over a hemisphere
// of directions (the principal axes among them) are scored by the share of area-sampled surface
// points they map back within a coarse tolerance of the surface (a grid of the part's size); the
// best few axes per order are refined on a fine grid (SurfaceGrid at the caller's tolerance) by a
// local search over the axis direction and the pivot, and scored there.

#include "vision/model/mesh.hpp"
#include "vision/model/surface_grid.hpp"

#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace mfcd::vision {

struct MeshTurnParams {
  int surface_points = 1500;      // area-weighted surface samples for the fine score
  int coarse_points = 256;        // ... and for the coarse scan over axes
  int axis_samples = 1000;        // axis directions over a hemisphere in the coarse scan
  int max_order = 24;             // rotations by 360/N for N = 2..max_order
  double symmetry_share = 0.998;  // a turn mapping at least this share onto the surface is a symmetry
  double near_share = 0.6;        // ... at least this (and less than symmetry_share): a near-symmetry
  double phase_share = 0.4;       // phase turns: this share of the period
  int refine_per_order = 3;       // best coarse axes per order refined on the fine grid
  void validate() const;          // throws std::invalid_argument naming the field
};

struct MeshTurn {
  enum class Kind { symmetry, near_symmetry, turn_over, phase };
  Kind kind = Kind::turn_over;
  cv::Matx33d R = cv::Matx33d::eye();  // the rotation, model frame: x -> R (x - pivot) + pivot
  cv::Vec3d pivot_mm{0, 0, 0};
  cv::Vec3d axis{0, 0, 1};  // unit rotation axis
  int order = 2;            // rotations: 360/order degrees (phase: the period's order)
  double on_surface = 0;    // share of the surface samples mapped onto the surface (fine)
};

struct MeshTurns {
  cv::Vec3d centroid_mm{0, 0, 0};                   // area-weighted surface centroid
  cv::Matx33d principal_axes = cv::Matx33d::eye();  // rows: unit axes, largest variance first; a rotation
  // Rotational symmetries: per axis the highest order found (kind symmetry); an axis about which
  // every order up to max_order is a symmetry is continuous (order 0).
  std::vector<MeshTurn> symmetries;
  // The turns worth checking a pose against: near-symmetries, turns over and phase turns, one per
  // class modulo the symmetries.
  std::vector<MeshTurn> alternatives;
};

// `fine` decides what lies on the surface (e.g. SurfaceGrid(mesh, 0.25, 0.5)); a coarse grid of the
// part's size is made inside. Deterministic. Throws std::invalid_argument on an empty mesh.
MeshTurns find_mesh_turns(const Mesh& mesh, const SurfaceGrid& fine, const MeshTurnParams& params = {});

// What counts as the part's own surface for its turns: within 0.2 % of its diameter (at least
// 0.1 mm, at most 0.5 mm), the tolerance the generalization bench finds its models' symmetries
// with (a hex head turned by 15 degrees moves its corners by ~3 % of its width, which a 0.5 mm
// tolerance calls the same part when the head is 10 mm across). Voxels at most half of it,
// coarser for a part whose box would need more than 64 M of them.
SurfaceGrid turn_surface(const Mesh& mesh, double diameter_mm);

// The turns of a part of diameter `diameter_mm` (BOP models_info's) on turn_surface: what mfc-teach
// stores in the template database (TemplateDatabase::turns).
MeshTurns find_part_turns(const Mesh& mesh, double diameter_mm, const MeshTurnParams& params = {});

// One line for a person teaching the part: its symmetries ("6-fold", "continuous", "none") and the
// turns its poses are checked against by kind, e.g. "symmetry none; checked: 2 turned over, 23
// near-symmetric (24-fold, 0.98 on the surface), 2 phase".
std::string describe(const MeshTurns& turns);

// Area-weighted surface samples of `mesh`, deterministic (stratified over the area, golden-ratio
// barycentric coordinates).
std::vector<cv::Vec3d> sample_surface(const Mesh& mesh, int count);

// Rotation by `angle` radians about the unit `axis` (Rodrigues).
cv::Matx33d axis_rotation(const cv::Vec3d& axis, double angle);

// The share of `points` that `R` about `pivot` maps onto `surface`.
double share_on_surface(const std::vector<cv::Vec3d>& points, const SurfaceGrid& surface, const cv::Matx33d& R,
                        const cv::Vec3d& pivot);

}  // namespace mfcd::vision
