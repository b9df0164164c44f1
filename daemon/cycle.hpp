#pragma once
// What one pick cycle carries between the daemon's threads. Every type here is fixed-size and
// preallocated in a ring slot, so the frame path copies into slots that already exist.
#include <algorithm>
#include <array>
#include <chrono>
#include <cstdint>
#include <cstring>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "mfcd/hal/sequencer.hpp"
#include "motion/robot_report.hpp"
#include "vision/camera/frame_undistorter.hpp"
#include "vision/camera/mfc_frames.hpp"

namespace mfcd::daemon {

using Clock = std::chrono::steady_clock;

// Milliseconds from a to b.
inline double ms_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

enum class CycleOrigin : std::uint8_t { Plc, Control, Continuous, Benchmark };
const char* to_string(CycleOrigin o);

// Error codes published in ERROR_CODE (docs/operations.md lists them).
enum class CycleError : std::uint16_t {
  None = 0,
  UnknownRecipe = 1,   // RECIPE_ID not in the configuration
  Capture = 2,         // camera or LEDs failed (HalError)
  Vision = 3,          // the vision stage threw
  Transform = 4,       // the chosen pick could not be transformed into the robot base frame
  Abandoned = 5,       // the daemon stopped before the cycle finished
  Calibrating = 6,     // a calibration session is running (mfcd-ctl calibrate): picking is paused
  Unavailable = 7,     // the cell could not take the job (no cell running, or its request queue full)
  NoRobotPose = 8,     // eye-in-hand: the robot pose block holds no valid pose for the capture
  NoGripperCheck = 9,  // CHECK_GRIP: gripper_check is not configured, or the checked pick is unknown
};

// Where the simulated cell puts its calibration plate for a calibration capture (real cells
// ignore it: the robot or the operator has put the real plate in view).
struct PlateRequest {
  enum class Kind : std::uint8_t {
    None,       // the cell as it is (the bin)
    Camera,     // at `pose` in the camera frame (intrinsics: mfcd-ctl calibrate capture --sim-plate-pose)
    EyeToHand,  // `pose` is the flange pose; plate on the flange, camera fixed (the sim's true transforms)
    EyeInHand,  // `pose` is the flange pose; camera on the flange, plate in the cell
  };
  Kind kind = Kind::None;
  std::array<double, 6> pose{};  // x, y, z mm, rx, ry, rz deg, R = Rz Ry Rx
};

struct CycleRequest {
  // CalibrationCapture: one frame set whose ambient image goes to the calibration session
  // instead of the vision pipeline. GripCheck: one image of the gripper camera, checked against
  // part obj_id at grip_camera_T_part (gripper_check).
  enum class Kind : std::uint8_t { Capture, RemovePicked, Refill, CalibrationCapture, GripCheck };
  Kind kind = Kind::Capture;
  CycleOrigin origin = CycleOrigin::Plc;
  std::uint64_t cycle_id = 0;
  std::uint16_t job_id = 0;
  std::uint16_t recipe_id = 0;
  std::uint16_t mode = 0;  // 0 = pick, 1 = count only
  int obj_id = 0;
  bool snapshot = false;
  Clock::time_point trigger{};
  Clock::time_point deadline{};
  // RemovePicked: where the robot took a part, in the frame of the camera that saw it (on the
  // flange at base_T_flange when flange_valid).
  cv::Vec3d picked_t_cam_mm{0, 0, 0};
  cv::Matx33d picked_R_cam = cv::Matx33d::eye();  // and the part's orientation as vision saw it
  PlateRequest plate;                             // CalibrationCapture, simulated cell
  // Eye-in-hand: the flange pose in the robot base frame at the capture (the PLC's robot pose
  // block when the job started); picks are base_T_flange * flange_T_camera * cam_T_part.
  bool flange_valid = false;
  Eigen::Isometry3d base_T_flange = Eigen::Isometry3d::Identity();
  // A second look (COMMAND LOOK): this capture, from base_T_flange, is fused with the first look
  // taken by cycle `first_cycle` from first_base_T_flange; the result is in the first camera's
  // frame and its picks are transformed with first_base_T_flange.
  bool second_look = false;
  std::uint64_t first_cycle = 0;
  Eigen::Isometry3d first_base_T_flange = Eigen::Isometry3d::Identity();
  // GripCheck: the part's ideal pose in the gripper camera (model -> camera, mm), and the job
  // whose pick is checked.
  Eigen::Isometry3d grip_camera_T_part = Eigen::Isometry3d::Identity();
  std::uint16_t grip_of_job = 0;
  // Refill: the simulated bin looked empty to vision (nothing found): the operator refills it.
};

// Ground truth of the simulated bin at capture (camera frame); empty on real hardware.
struct SimTruth {
  static constexpr int kMaxParts = 16;
  struct Part {
    int obj_id = 0;
    cv::Matx33d R = cv::Matx33d::eye();
    cv::Vec3d t_mm{0, 0, 0};
  };
  int count = 0;
  std::array<Part, kMaxParts> parts{};
};

inline void copy_message(char* dst, std::size_t size, const char* src) {
  const std::size_t n = std::min(std::strlen(src), size - 1);
  std::memcpy(dst, src, n);
  dst[n] = '\0';
}

// One FrameSet in the acquisition -> vision ring. The images are allocated once before the
// threads start; `mfc` holds cv::Mat headers over them (no copy, no allocation per cycle).
struct FrameSlot {
  CycleRequest request;
  hal::FrameSet frames;
  vision::MfcFrames mfc;
  bool ok = false;
  char error[256] = {};
  double capture_ms = 0;
  Clock::time_point captured{};
  SimTruth truth;
  hal::LedMask leds_after = 0;  // LED state right after the capture (must be 0)
  cv::Mat1b gripper;            // GripCheck: the gripper camera's image (allocated when configured)

  void allocate(const hal::ImageFormat& format);
};

// Copies a FrameSet into a preallocated one of the same format (memcpy per image).
void copy_frame_set(const hal::FrameSet& from, hal::FrameSet& to);
// The same, each image undistorted by `undistorter` into the preallocated one (cv::remap, no
// allocation); a plain copy_frame_set when the undistorter is not active().
void copy_frame_set(const hal::FrameSet& from, hal::FrameSet& to, const vision::FrameUndistorter& undistorter);

struct CandidateOut {
  int obj_id = 0;
  float score = 0;
  float cost_px = 0;
  bool refined = false;
  cv::Matx33d R_cam = cv::Matx33d::eye();
  cv::Vec3d t_cam_mm{0, 0, 0};
  motion::PickPose base;  // in the robot base frame
  bool base_valid = false;
  float utility = -1;          // pick-choice utility, -1 = not eligible
  float grasp_visibility = 1;  // vision::PoseCandidate::grasp_visibility
  bool ambiguous = false;      // vision::PoseCandidate::ambiguous
  cv::Rect2d box;              // image bounding box of the matched template (snapshot overlays)
};

// One cycle's outcome, vision -> main thread.
struct CycleResult {
  static constexpr int kMaxCandidates = 16;
  // CalibrationImage: the ambient image of a CalibrationCapture is in Cell::calibration_image()
  // (error/message say why not), valid until the next calibration capture is submitted.
  enum class Kind : std::uint8_t { Cycle, SnapshotSaved, CalibrationImage };
  Kind kind = Kind::Cycle;
  CycleRequest request;
  CycleError error = CycleError::None;
  char message[256] = {};
  bool degraded = false;
  int candidate_count = 0;
  std::array<CandidateOut, kMaxCandidates> candidates{};
  int chosen = -1;
  // Eligible candidates with a robot-base pose, best first (motion::rank_picks): ranked[0] ==
  // chosen; NEXT on the robot link walks the rest.
  std::array<std::uint16_t, kMaxCandidates> ranked{};
  int ranked_count = 0;
  double capture_ms = 0, queue_ms = 0, vision_ms = 0, choice_ms = 0, total_ms = 0;
  double edges_ms = 0, lines_ms = 0, distance_ms = 0, search_ms = 0, pose_ms = 0, refine_ms = 0;
  int edge_pixels = 0;
  int search_rounds = 0;   // search rounds the pipeline ran (vision.search_rounds; fewer near the deadline)
  bool escalated = false;  // the pipeline's wide search ran (vision.escalate_below)
  // The first look asks for a second (config second_look; no pick is published then): the
  // flange pose to take it from, robot base frame, and why (motion::LookReason's codes).
  bool look_wanted = false;
  std::uint16_t look_reason = 0;
  int look_candidate = -1;  // the candidate the second camera is centred on
  motion::PickPose look_pose;
  // A gripper check (CycleRequest::Kind::GripCheck): motion::reg::GripState's code, the part
  // measured in the tool frame (mm/deg; zero unless found), measured vs ideal, and the fit's mean
  // edge distance and matched share of model edge points; `message` says why that state.
  std::uint16_t grip_state = 0;
  motion::PickPose grip_pose;
  float grip_translation_mm = 0, grip_rotation_deg = 0;
  float grip_cost_px = 0, grip_inliers = 0;
  SimTruth truth;
  bool leds_off = true;
  char snapshot_dir[256] = {};
};

}  // namespace mfcd::daemon
