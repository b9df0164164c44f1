#pragma once
// Scoring of pose estimates for the paper's evaluation (Sec. 5.1.1): symmetry-aware pose error
// and the correctness criterion of Table 1, plus the parts table (config/parts/parts.csv) that
// says which symmetry each part has.

#include "vision/dataset/bop_dataset.hpp"
#include "vision/pose/grasp_visibility.hpp"
#include "vision/templates/template_database.hpp"

#include <opencv2/core.hpp>

#include <filesystem>
#include <string>
#include <vector>

namespace mfcd::eval {

struct PartEntry {
  std::string name;
  int obj_id = 0;
  vision::PartSymmetry symmetry;        // what counts as the same pose (errors are symmetry-aware)
  vision::PartSymmetry views_symmetry;  // what mfc-teach folds the views by (a subgroup of it)
  int views = 300;                      // K, the views over the whole sphere mfc-teach samples
};

// Reads config/parts/parts.csv ('#' comments, header "name,obj_id,symmetry[,views_symmetry[,views]]";
// views_symmetry defaults to symmetry, views to 300). Throws std::runtime_error naming the file,
// line and reason (missing file, wrong field count, bad obj_id, bad symmetry, a views_symmetry
// that is not a subgroup of symmetry, views not an integer in 1..100000, duplicate name or obj_id).
std::vector<PartEntry> read_parts_csv(const std::filesystem::path& file);
// The entry with this obj_id; throws std::runtime_error naming `source` when there is none.
const PartEntry& part_by_id(const std::vector<PartEntry>& parts, int obj_id, const std::string& source);

// Grasp features of the parts (config/parts/grasp-features.csv): '#' comments, header
// "name,obj_id,x_mm,y_mm,z_mm,radius_mm,approach_x,approach_y,approach_z,max_tilt_deg", one line
// per feature, several per part allowed. Throws std::runtime_error naming the file, line and
// reason (missing file, field count, a number that is not one, an obj_id not in `parts` or
// given with another part's name, GraspFeature::validate's reasons).
std::vector<std::pair<int, vision::GraspFeature>> read_grasp_features_csv(const std::filesystem::path& file,
                                                                          const std::vector<PartEntry>& parts);

// The reference for the grasp-feature estimate (vision/pose/grasp_visibility.hpp): how free a
// feature of a ground-truth instance is in the rendered scene. 0 when it faces away from the
// camera (grasp_faces_camera at the true pose) or its disc lies mostly off the instance's
// silhouette (`mask`: less than a fifth of the disc's pixels, e.g. a bore seen edge-on); else the
// share of the disc's silhouette pixels that are visible (`mask_visib`). The disc is the
// feature's radius at the spot's distance, around its projection.
double true_grasp_visibility(const vision::GraspFeature& feature, const cv::Matx33d& R, const cv::Vec3d& t_mm,
                             const vision::PinholeCamera& camera, const cv::Mat1b& mask, const cv::Mat1b& mask_visib);

// Errors of an estimate against one ground-truth pose, after choosing the ground-truth pose's
// symmetric equivalent (R_gt * S, S a model symmetry about the model z axis through the model
// origin) that is closest in rotation to the estimate.
struct PoseError {
  double position_mm = 0;       // distance between the part centre (`centre_mm`, model frame) as placed by each pose
  double rotation_deg = 0;      // angle of R_est * R_gt'^T; for z:inf the angle between the model z axes
  cv::Vec3d d_t_mm{0, 0, 0};    // estimate minus truth of the part centre, camera axes
  cv::Vec3d abs_t_mm{0, 0, 0};  // |d_t_mm| per axis
  // |rx|, |ry|, |rz| of the relative rotation R_est * R_gt'^T = Rz(rz) Ry(ry) Rx(rx), camera axes, degrees.
  cv::Vec3d abs_r_deg{0, 0, 0};
  // Unit axis of that relative rotation, camera axes (z = the optical axis); 0 when there is no
  // rotation. Tells a turn about the line of sight from a part turned over.
  cv::Vec3d axis_cam{0, 0, 0};
};

PoseError pose_error(const cv::Matx33d& R_est, const cv::Vec3d& t_est, const cv::Matx33d& R_gt, const cv::Vec3d& t_gt,
                     const vision::PartSymmetry& symmetry, const cv::Vec3d& centre_mm = {0, 0, 0});

// The same against a model's symmetries given as rigid transforms S of the model frame (mm),
// p_model -> S p_model, that leave the model the same (BOP's models_info convention); the
// equivalent ground truth is (R_gt R_S, R_gt t_S + t_gt), the one closest in rotation to the
// estimate. `symmetries` must hold the identity.
PoseError pose_error(const cv::Matx33d& R_est, const cv::Vec3d& t_est, const cv::Matx33d& R_gt, const cv::Vec3d& t_gt,
                     const std::vector<cv::Matx44d>& symmetries, const cv::Vec3d& centre_mm = {0, 0, 0});

// Every symmetry transform of a BOP model, identity first: its symmetries_discrete, and each
// continuous symmetry sampled every `continuous_step_deg` about its axis through its offset,
// composed with each discrete one (as the BOP toolkit's get_symmetry_transformations does).
std::vector<cv::Matx44d> symmetry_transforms(const vision::BopModelInfo& info, double continuous_step_deg = 1.0);

// The criterion of Table 1: position within `max_position_mm` and rotation angle within
// `max_rotation_deg` (the total angle; stricter than asking each of three Euler angles of the
// relative rotation to be within it).
struct Criterion {
  double max_position_mm = 5.0;
  double max_rotation_deg = 10.0;
  bool accepts(const PoseError& e) const {
    return e.position_mm <= max_position_mm && e.rotation_deg <= max_rotation_deg;
  }
};

// Angle of a rotation matrix, degrees (numerically safe near 0 and 180).
double rotation_angle_deg(const cv::Matx33d& R);
// x-y-z Euler angles (R = Rz(z) Ry(y) Rx(x)), degrees.
cv::Vec3d euler_xyz_deg(const cv::Matx33d& R);

}  // namespace mfcd::eval
