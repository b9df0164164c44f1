#include "daemon/report.hpp"

#include <algorithm>
#include <cstring>
#include <ctime>
#include <fstream>
#include <stdexcept>

#include "daemon/look_planner.hpp"
#include "motion/pick_transform.hpp"
#include "tools/common/build_version.hpp"

namespace mfcd::daemon {

using nlohmann::json;

std::optional<motion::PickPose> base_pose(const DaemonConfig& config, const cv::Matx33d& R, const cv::Vec3d& t,
                                          const CycleRequest& request) {
  Eigen::Isometry3d cam_T_part = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) cam_T_part.linear()(r, k) = R(r, k);
    cam_T_part.translation()(r) = t[r];
  }
  return motion::PickTransform(config.hand_eye)
      .pick_pose(cam_T_part, request.flange_valid ? std::optional(request.base_T_flange) : std::nullopt);
}

json pose_json(const motion::PickPose& p) {
  return {{"x", p.x_mm}, {"y", p.y_mm}, {"z", p.z_mm}, {"rx", p.rx_deg}, {"ry", p.ry_deg}, {"rz", p.rz_deg}};
}

namespace {
json mat_json(const cv::Matx33d& R) {
  json a = json::array();
  for (int i = 0; i < 9; ++i) a.push_back(R.val[i]);
  return a;
}
const char* error_name(CycleError e) {
  switch (e) {
    case CycleError::None:
      return "none";
    case CycleError::UnknownRecipe:
      return "unknown recipe";
    case CycleError::Capture:
      return "capture failed";
    case CycleError::Vision:
      return "vision failed";
    case CycleError::Transform:
      return "pick transform failed";
    case CycleError::Abandoned:
      return "abandoned";
    case CycleError::Calibrating:
      return "calibrating";
    case CycleError::Unavailable:
      return "cell unavailable";
    case CycleError::NoRobotPose:
      return "no robot pose";
    case CycleError::NoGripperCheck:
      return "no gripper check";
  }
  return "?";
}
}  // namespace

json result_json(const CycleResult& r, const DaemonConfig& config) {
  json j;
  j["version"] = version();  // which mfcd made the result (result.json outlives the daemon)
  j["commit"] = git_commit();
  j["cycle"] = r.request.cycle_id;
  j["origin"] = to_string(r.request.origin);
  j["job_id"] = r.request.job_id;
  j["recipe"] = r.request.recipe_id;
  if (const RecipeConfig* rc = config.recipe(r.request.recipe_id)) j["part"] = rc->part;
  j["mode"] = r.request.mode == 0 ? "pick" : "count";
  j["error_code"] = static_cast<int>(r.error);
  j["error"] = error_name(r.error);
  if (r.message[0]) j["message"] = r.message;
  // Eye-in-hand: the flange pose the picks were transformed with.
  if (r.request.flange_valid) {
    const motion::PoseXYZ f = motion::isometry_to_pose(r.request.base_T_flange);
    j["robot_pose"] = {{"x", f.position_mm.x()},  {"y", f.position_mm.y()},  {"z", f.position_mm.z()},
                       {"rx", f.rotation.rx_deg}, {"ry", f.rotation.ry_deg}, {"rz", f.rotation.rz_deg}};
  }
  // A second look: its candidates are in the first look's camera frame, its picks transformed with
  // that look's flange pose.
  if (r.request.second_look) {
    const motion::PoseXYZ f = motion::isometry_to_pose(r.request.first_base_T_flange);
    j["second_look"] = {{"first_cycle", r.request.first_cycle},
                        {"first_robot_pose",
                         {{"x", f.position_mm.x()},
                          {"y", f.position_mm.y()},
                          {"z", f.position_mm.z()},
                          {"rx", f.rotation.rx_deg},
                          {"ry", f.rotation.ry_deg},
                          {"rz", f.rotation.rz_deg}}}};
  }
  if (r.request.kind == CycleRequest::Kind::GripCheck) {
    static const char* const states[] = {"none", "expected", "pose_error", "not_grasped"};
    j["grip_check"] = {
        {"of_job", r.request.grip_of_job},           {"state", states[std::min<std::size_t>(r.grip_state, 3)]},
        {"tool_T_part", pose_json(r.grip_pose)},     {"translation_error_mm", r.grip_translation_mm},
        {"rotation_error_deg", r.grip_rotation_deg}, {"cost_px", r.grip_cost_px},
        {"inlier_fraction", r.grip_inliers}};
  }
  if (r.look_wanted)
    j["look_wanted"] = {{"reason", to_string(static_cast<LookReason>(r.look_reason))},
                        {"candidate", r.look_candidate},
                        {"flange", pose_json(r.look_pose)}};
  j["degraded"] = r.degraded;
  j["overrun"] = r.total_ms > config.cycle_budget_ms;
  j["leds_off_after_capture"] = r.leds_off;
  j["times_ms"] = {{"capture", r.capture_ms}, {"queue", r.queue_ms},       {"vision", r.vision_ms},
                   {"choice", r.choice_ms},   {"total", r.total_ms},       {"edges", r.edges_ms},
                   {"lines", r.lines_ms},     {"distance", r.distance_ms}, {"search", r.search_ms},
                   {"pose", r.pose_ms},       {"refine", r.refine_ms}};
  j["budget_ms"] = config.cycle_budget_ms;
  j["edge_pixels"] = r.edge_pixels;
  j["search_rounds"] = r.search_rounds;
  j["escalated"] = r.escalated;
  json cands = json::array();
  for (int i = 0; i < r.candidate_count; ++i) {
    const CandidateOut& c = r.candidates[static_cast<std::size_t>(i)];
    json cj = {{"obj_id", c.obj_id},
               {"score", c.score},
               {"cost_px", c.cost_px},
               {"refined", c.refined},
               {"utility", c.utility},
               {"grasp_visibility", c.grasp_visibility},
               {"ambiguous", c.ambiguous},
               {"R_cam", mat_json(c.R_cam)},
               {"t_cam_mm", {c.t_cam_mm[0], c.t_cam_mm[1], c.t_cam_mm[2]}}};
    if (c.base_valid) cj["base"] = pose_json(c.base);
    cands.push_back(std::move(cj));
  }
  j["candidates"] = std::move(cands);
  j["chosen"] = r.chosen;
  // The pick order (candidate indices, best first) the robot link's NEXT walks.
  j["ranked"] = std::vector<int>(r.ranked.begin(), r.ranked.begin() + std::max(0, r.ranked_count));
  if (r.chosen >= 0) {
    const CandidateOut& c = r.candidates[static_cast<std::size_t>(r.chosen)];
    j["pick"] = pose_json(c.base);
    j["pick"]["score"] = c.score;
    j["pick"]["obj_id"] = c.obj_id;
  }
  if (r.truth.count > 0) {
    json truth = json::array();
    for (int i = 0; i < r.truth.count; ++i) {
      const SimTruth::Part& p = r.truth.parts[static_cast<std::size_t>(i)];
      json tj = {{"obj_id", p.obj_id}, {"R_cam", mat_json(p.R)}, {"t_cam_mm", {p.t_mm[0], p.t_mm[1], p.t_mm[2]}}};
      if (const auto b = base_pose(config, p.R, p.t_mm, r.request)) tj["base"] = pose_json(*b);
      truth.push_back(std::move(tj));
    }
    j["sim_truth"] = std::move(truth);
  }
  if (r.snapshot_dir[0]) j["snapshot"] = r.snapshot_dir;
  return j;
}

vision::PipelineResult overlay_candidates(const CycleResult& result,
                                          const std::vector<std::pair<int, std::string>>& parts) {
  vision::PipelineResult out;
  for (int i = 0; i < result.candidate_count; ++i) {
    const CandidateOut& c = result.candidates[static_cast<std::size_t>(i)];
    vision::PoseCandidate p;
    p.obj_id = c.obj_id;
    for (const auto& [id, name] : parts)
      if (id == c.obj_id) p.part = name;
    p.R_m2c = c.R_cam;
    p.t_m2c_mm = c.t_cam_mm;
    p.score = c.score;
    p.box = c.box;
    out.candidates.push_back(p);
  }
  return out;
}

}  // namespace mfcd::daemon
