// What flows between the daemon and the robot links (Modbus/TCP server, SocketCAN publisher).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace mfcd::motion {

// A pick in the robot base frame: millimetres and degrees, R = Rz(rz) * Ry(ry) * Rx(rx)
// (see euler.hpp and docs/register-map.md).
struct PickPose {
  float x_mm = 0, y_mm = 0, z_mm = 0;
  float rx_deg = 0, ry_deg = 0, rz_deg = 0;
};

// One pick of a job's ranked list (the order motion::rank_picks gives; NEXT walks it).
struct RankedPick {
  PickPose pick;
  float score = 0;
  std::uint16_t candidate_index = 0;  // among the cycle's candidates
  std::uint16_t reserved = 0;
};
inline constexpr std::size_t kMaxRankedPicks = 8;

// Published by the daemon whenever its state or a job result changes. One writer only.
// Every field is a plain 32-bit-or-smaller value so the snapshot can be copied word by word.
struct RobotReport {
  std::uint16_t job_id = 0;      // job this result answers; 0 = none yet
  std::uint16_t recipe_id = 0;   // recipe the result was made with
  std::uint16_t error_code = 0;  // 0 = no error; anything else sets the ERROR bit
  std::uint16_t objects_remaining = 0;
  std::uint16_t cycle_time_ms = 0;  // trigger to result
  std::uint16_t candidate_index = 0;
  std::uint16_t candidate_count = 0;
  std::uint16_t ready = 0;       // 1: daemon can take a trigger (camera open, recipe loaded)
  std::uint16_t vision_ok = 0;   // 1: camera and vision pipeline healthy
  std::uint16_t pick_valid = 0;  // 1: pick/score hold a pick for job_id
  PickPose pick;                 // the pick of rank pick_rank (its score and candidate_index above and below)
  float score = 0;
  // The job's picks in order, ranked[0] the first choice; pick_count 0 when the report carries
  // only `pick` (no fall-backs). NEXT on the Modbus link publishes ranked[pick_rank + 1] at
  // once; the daemon then follows with pick_rank (the CAN link sends the pick of that rank).
  std::uint16_t pick_rank = 0;
  std::uint16_t pick_count = 0;
  std::uint16_t snapshots_saved = 0;  // snapshots written since mfcd started, wraps
  std::uint16_t reserved = 0;
  // Second look (eye-in-hand): 1 when the result of job_id asks the robot to take the camera to
  // look_pose (the flange pose in the robot base frame, mm/deg like `pick`) for a LOOK; then
  // pick_valid is 0 (the Modbus link shows no pick for such a report). look_reason says why
  // (reg::LookReason); both 0 and look_pose zero when no second look is wanted.
  std::uint16_t look_wanted = 0;
  std::uint16_t look_reason = 0;
  PickPose look_pose;
  // Gripper check: the result of a CHECK_GRIP job (job_id is the check's job). grip_state is
  // reg::GripState, 0 in every other result; grip_of_job the job whose pick was checked
  // (PlcCommand::check_of_job). grip_pose is the measured pose of the part in the tool frame
  // (tool_T_part: mm/deg, R = Rz * Ry * Rx like `pick`), grip_translation_mm and
  // grip_rotation_deg how far it is from the ideal tool_T_part (distance of the part origins,
  // angle of the relative rotation); all three are shown only for Expected and PoseError.
  // pick_valid is 0 in a check's result.
  std::uint16_t grip_state = 0;
  std::uint16_t grip_of_job = 0;
  PickPose grip_pose;
  float grip_translation_mm = 0, grip_rotation_deg = 0;
  std::array<RankedPick, kMaxRankedPicks> ranked{};
};

// The robot pose block (registers 36..49) as the PLC last wrote it.
struct RobotPoseReading {
  std::uint32_t writes = 0;    // accepted writes to the block; 0 = never written
  std::uint16_t valid = 0;     // ROBOT_POSE_VALID
  std::uint16_t sequence = 0;  // ROBOT_POSE_SEQ
  float x_mm = 0, y_mm = 0, z_mm = 0;
  float rx_deg = 0, ry_deg = 0, rz_deg = 0;
};

// Written by the PLC (Modbus) and handed to the daemon.
//   Trigger, SaveScene: start job job_id (SaveScene also keeps its frame set as a snapshot);
//   Reset: clear an error, abandon a pending job;
//   Next: the server has already published the pick of rank `rank` of job job_id;
//   PickResult: not a COMMAND but a PICK_RESULT write: `outcome` (reg::PickOutcome) of the
//   pick of rank `rank` of job job_id;
//   Look: start job job_id like Trigger (recipe_id, mode; the robot pose block read at job
//   start), taking the second frame set at the robot's current pose and fusing it with the
//   first look of job look_of_job, whose published result asked for it (look_wanted);
//   CheckGrip: start job job_id (recipe_id, mode) that checks the part in the gripper after the
//   robot took the pick of rank `rank` of job check_of_job, whose published result had a pick
//   (pick_valid); the job's result carries grip_state and no pick.
// Kind's values are not COMMAND codes (reg::Command); the server maps one to the other.
struct PlcCommand {
  enum class Kind : std::uint16_t {
    Trigger = 1,
    Reset = 2,
    Next = 3,
    SaveScene = 4,
    PickResult = 5,
    Look = 6,
    CheckGrip = 7
  };
  Kind kind = Kind::Trigger;
  std::uint16_t job_id = 0;
  std::uint16_t recipe_id = 0;
  std::uint16_t mode = 0;
  std::uint16_t rank = 0;
  std::uint16_t outcome = 0;
  std::uint16_t look_of_job = 0;   // Look: the job (JOB_ID_ECHO when LOOK was taken) whose look it continues
  std::uint16_t check_of_job = 0;  // CheckGrip: the job (JOB_ID_ECHO when CHECK_GRIP was taken) whose pick it checks
};

}  // namespace mfcd::motion
