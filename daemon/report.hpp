#pragma once
// JSON views of a cycle (control socket, snapshots) and the snapshot writer. Off the frame path.
#include <nlohmann/json.hpp>

#include <string>

#include "daemon/config.hpp"
#include "daemon/cycle.hpp"
#include "vision/pipeline/bin_picking_pipeline.hpp"

namespace mfcd::daemon {

class RetainedJob;
class VisionStage;

// The pick pose of a camera-frame part pose in the robot base frame (hand-eye calibration plus
// part_T_grasp), or nullopt when it cannot be expressed.
std::optional<motion::PickPose> basePose(const DaemonConfig& config, const cv::Matx33d& R, const cv::Vec3d& t_mm);

nlohmann::json poseJson(const motion::PickPose& p);
// Everything about one cycle: mfcd's version, request, error, times, candidates (camera and base
// frame), the chosen pick, and on the simulated cell the bin's ground truth (camera and base frame).
nlohmann::json resultJson(const CycleResult& result, const DaemonConfig& config);

// Saves the kept cycle's 9 images, its depth edges, an overlay of its candidates and result.json
// (with `reason`: why it was saved) into a new directory under config.snapshots.directory, first
// deleting the oldest snapshots while the directory's size would exceed the quota. Returns the
// new directory. Throws std::runtime_error naming the path on failure.
std::string saveSnapshot(const DaemonConfig& config, const RetainedJob& job, const VisionStage* stage, const char* reason);

}  // namespace mfcd::daemon
