#pragma once
// The part of the image a teaching render needs (the template views, the edge offset plate):
// rendering only it costs a fraction of the whole image.

#include "vision/camera/camera.hpp"
#include "vision/model/mesh.hpp"

#include <opencv2/core.hpp>

namespace mfcd::vision {

// The widest shadow (px) any of the camera's flashes casts from an edge at depth `near_mm` onto
// a surface at `far_mm`: baseline * f * (far - near) / (near * far) for the farthest LED.
double widest_shadow_px(const CameraConfig& config, double near_mm, double far_mm);

// Half the side of a square window that holds an object of image radius `object_px`, the widest
// shadow it casts from depth `near_mm` onto a surface at `far_mm` and an 8 px margin.
int window_half_px(const CameraConfig& config, double object_px, double near_mm, double far_mm);

// The window of that half side around the principal point, clipped to the image.
cv::Rect window_on_axis(const PinholeCamera& cam, int half);

// The pixels of `camera`'s image that a render of `mesh` at p_camera = R * p_mesh + t, in front
// of a surface at depth `far_mm`, can show the part or its shadows in: the box of its projected
// vertices (the image of a triangle lies within its vertices') grown by the widest shadow cast
// from its nearest vertex onto that surface and the 8 px margin window_half_px keeps, clipped to
// the image. Depth edges need a 3x3 neighbourhood around them, which the margin holds.
cv::Rect part_region(const CameraConfig& config, const PinholeCamera& camera, const Mesh& mesh, const cv::Matx33d& R,
                     const cv::Vec3d& t, double far_mm);

}  // namespace mfcd::vision
