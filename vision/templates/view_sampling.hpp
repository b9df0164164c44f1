#pragma once
// Out-of-plane rotations for the template database (paper Sec. 4.3): viewing directions
// spread uniformly over the sphere, reduced by the part's symmetry, each turned into the
// rotation of a camera looking at the part centre from that direction.

#include "vision/templates/template_database.hpp"

#include <opencv2/core.hpp>

#include <vector>

namespace mfcd::vision {

// K directions on the unit sphere from the Fibonacci (golden-angle) spiral: point i has
// z = 1 - (2i + 1)/K and azimuth i * 137.5 deg, so every direction covers the same area
// (4 pi / K) and neighbours are sqrt(4 pi / K) apart (11.7 deg for K = 300).
std::vector<cv::Vec3d> fibonacci_sphere(int K);

// Viewing directions (model frame, from the part centre towards the camera) for a database of
// density K: all K for an asymmetric part; for an N-fold symmetry about z only those with
// azimuth in [0, 360/N) (about K/N); for continuous symmetry about z one meridian sampled at
// the same spacing (about pi / sqrt(4 pi / K) + 1 directions).
std::vector<cv::Vec3d> template_view_directions(int K, const PartSymmetry& symmetry);

// The model-to-camera rotation of a camera at direction `d` looking at the part centre, with a
// fixed roll (the in-plane angle is searched by FDCM): the camera's +z points along -d and its
// +x is as close as possible to the model's x-y plane.
cv::Matx33d view_rotation(const cv::Vec3d& d);

}  // namespace mfcd::vision
