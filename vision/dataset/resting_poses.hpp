#pragma once
// Where a rigid part can come to rest on a flat floor: the faces of its convex hull whose
// support polygon contains the vertical projection of the centre of mass.

#include "vision/model/mesh.hpp"

#include <opencv2/core.hpp>

#include <vector>

namespace mfcd::vision {

// Centre of mass of the solid bounded by a closed mesh, uniform density (signed tetrahedra
// from the origin). Falls back to the vertex mean for open or flat meshes.
cv::Vec3d centre_of_mass(const Mesh& mesh);

struct RestingPose {
  // Rotates the part's frame so that the support face's outward normal points along +z
  // (the camera's z, i.e. down into the bin: the camera looks down at the floor).
  cv::Matx33d R = cv::Matx33d::eye();
  cv::Vec3d face_normal;        // outward normal of the support face, part frame
  double support_area_mm2 = 0;  // area of the support polygon
  double com_margin_mm = 0;     // distance of the projected centre of mass inside the polygon
  // Solid angle the support polygon subtends at the centre of mass: the directions of gravity,
  // in the part's frame, under which it lands on this face (the quasi-static landing model).
  double solid_angle_sr = 0;
};

// Candidate support planes are the planes of the mesh's own triangles that have every
// vertex on one side (so they are faces of the convex hull); hull faces that are no mesh
// triangle (e.g. a wheel tilted onto rim and hub) are not found. A face is stable when the
// projected centre of mass lies at least min_margin_mm inside its support polygon.
// Coplanar triangles give one pose. Sorted by decreasing support area.
std::vector<RestingPose> stable_resting_poses(const Mesh& mesh, double min_margin_mm = 0.2);

}  // namespace mfcd::vision
