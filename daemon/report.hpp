#pragma once
// JSON views of a cycle (control socket, snapshots). Off the frame path.
#include <nlohmann/json.hpp>

#include <string>
#include <utility>
#include <vector>

#include "daemon/config.hpp"
#include "daemon/cycle.hpp"
#include "vision/pipeline/bin_picking_pipeline.hpp"

namespace mfcd::daemon {

// The pick pose of a camera-frame part pose in the robot base frame (hand-eye calibration plus
// part_T_grasp; eye-in-hand: with the request's flange pose), or nullopt when it cannot be expressed.
std::optional<motion::PickPose> base_pose(const DaemonConfig& config, const cv::Matx33d& R, const cv::Vec3d& t_mm,
                                          const CycleRequest& request);

nlohmann::json pose_json(const motion::PickPose& p);
// Everything about one cycle: mfcd's version, request, error, times, candidates (camera and base
// frame), the chosen pick, and on the simulated cell the bin's ground truth (camera and base frame).
nlohmann::json result_json(const CycleResult& result, const DaemonConfig& config);

// The candidates a cycle reported, as vision::draw_candidates draws them (with their part names
// from `parts`: obj_id, name).
vision::PipelineResult overlay_candidates(const CycleResult& result,
                                          const std::vector<std::pair<int, std::string>>& parts);

}  // namespace mfcd::daemon
