#pragma once
// A top-down height field over the bin on a regular x/y grid of the camera frame, filled
// by rasterising meshes on the CPU. Heights are millimetres above the bin floor
// (floor_z - z_camera: the camera looks down along +z). Used to drop parts onto the floor
// and onto parts already placed without interpenetration.

#include "vision/model/mesh.hpp"

#include <opencv2/core.hpp>

namespace mfcd::vision {

class HeightMap {
 public:
  // Covers x in [x0, x0 + cols * cell_mm), y likewise; all cells start at `initial`.
  HeightMap(double x0_mm, double y0_mm, int cols, int rows, double cell_mm, double floor_z_mm, float initial);

  // The upper surface (largest height per cell) or lower surface (smallest) of the mesh at
  // pose (R, t), camera frame. Cells the mesh does not cover keep their value (use
  // -inf / +inf as "empty"). Every triangle's interior is sampled at cell centres and its
  // edges every half cell, so thin and vertical features are not missed.
  void raise_to_top(const Mesh& mesh, const cv::Matx33d& R, const cv::Vec3d& t);
  void lower_to_bottom(const Mesh& mesh, const cv::Matx33d& R, const cv::Vec3d& t);

  cv::Mat1f& heights() { return h_; }
  const cv::Mat1f& heights() const { return h_; }
  double cell_mm() const { return cell_; }
  double floor_z_mm() const { return floor_z_; }
  cv::Point2d cell_centre(int col, int row) const { return {x0_ + (col + 0.5) * cell_, y0_ + (row + 0.5) * cell_}; }
  // Height at a camera-frame x/y (nearest cell); `outside` when off the grid.
  float at(double x_mm, double y_mm, float outside) const;

 private:
  void rasterise(const Mesh& mesh, const cv::Matx33d& R, const cv::Vec3d& t, bool top);
  double x0_, y0_, cell_, floor_z_;
  cv::Mat1f h_;
};

}  // namespace mfcd::vision
