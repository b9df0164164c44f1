// The Modbus holding-register map mfcd exposes to the PLC. docs/register-map.md is the
// PLC programmer's description of the same table; keep the two in step.
#pragma once

#include <cstdint>

namespace mfcd::motion::reg {

// Everything lives in one block of holding registers starting at protocol address 0, so a
// single "read holding registers" (FC 0x03) of kBlockSize covers the whole map.
inline constexpr std::uint16_t kBlockSize = 96;
// 2: robot pose block at 36..49; 3: NEXT, SAVE_SCENE, PICK_RESULT; 4: LOOK, LOOK_WANTED, 55..67;
// 5: CHECK_GRIP, 68..85
inline constexpr std::uint16_t kMapVersion = 5;

// --- Control block: written by the PLC ---------------------------------------------------
inline constexpr std::uint16_t kCommand = 0;   // command code, see Command; reads back 0 once taken
inline constexpr std::uint16_t kJobId = 1;     // job id for the next TRIGGER, SAVE_SCENE, LOOK or CHECK_GRIP (1..65535)
inline constexpr std::uint16_t kRecipeId = 2;  // part / recipe id for the next job
inline constexpr std::uint16_t kMode = 3;      // cycle mode for the next job, see Mode
// The outcome of the pick in the registers (JOB_ID_ECHO, PICK_RANK), see PickOutcome; a
// nonzero value written here is a report, taken when PICK_RESULT_JOB names JOB_ID_ECHO.
inline constexpr std::uint16_t kPickResult = 4;
inline constexpr std::uint16_t kPickResultJob = 5;  // the job a PICK_RESULT reports on
inline constexpr std::uint16_t kControlEnd = 6;     // 6..7 reserved: writes are refused
inline constexpr std::uint16_t kWritableEnd = 6;

// --- Status block: written by mfcd, read-only for the PLC --------------------------------
inline constexpr std::uint16_t kStatus = 8;       // status bits, see StatusBit
inline constexpr std::uint16_t kJobIdEcho = 9;    // job id of the result below
inline constexpr std::uint16_t kHeartbeat = 10;   // +1 every second, wraps at 65535
inline constexpr std::uint16_t kErrorCode = 11;   // 0 = no error
inline constexpr std::uint16_t kRecipeEcho = 12;  // recipe id the result was made with
inline constexpr std::uint16_t kObjectsRemaining = 13;
inline constexpr std::uint16_t kCycleTimeMs = 14;     // last cycle, trigger to result, saturates
inline constexpr std::uint16_t kCandidateIndex = 15;  // index of the chosen candidate
inline constexpr std::uint16_t kCandidateCount = 16;  // candidates found in the last cycle
inline constexpr std::uint16_t kWordOrder = 17;       // 0 = ABCD, 1 = CDAB (configured)
inline constexpr std::uint16_t kMapVersionReg = 18;
inline constexpr std::uint16_t kLastCommandResult = 19;  // 0 ok, else Modbus exception code of the last refused command

// --- Pick: float32 pairs in the configured word order -------------------------------------
inline constexpr std::uint16_t kPickX = 20;  // mm, robot base frame
inline constexpr std::uint16_t kPickY = 22;
inline constexpr std::uint16_t kPickZ = 24;
inline constexpr std::uint16_t kPickRx = 26;  // degrees, R = Rz(rz) * Ry(ry) * Rx(rx)
inline constexpr std::uint16_t kPickRy = 28;
inline constexpr std::uint16_t kPickRz = 30;
inline constexpr std::uint16_t kScore = 32;       // 0..1
inline constexpr std::uint16_t kTestVector = 34;  // always 123456.0f, to check the word order
inline constexpr float kTestVectorValue = 123456.0f;

// --- Robot pose: written by the PLC (map version 2) ----------------------------------------
// The robot flange pose in the base frame, for mfcd-ctl calibrate capture --pose-from-plc:
// float32 pairs in the configured word order, then a valid flag and a sequence number the PLC
// changes for every new pose. Write the whole block with one FC 0x10.
inline constexpr std::uint16_t kRobotPoseX = 36;  // mm
inline constexpr std::uint16_t kRobotPoseY = 38;
inline constexpr std::uint16_t kRobotPoseZ = 40;
inline constexpr std::uint16_t kRobotPoseRx = 42;  // degrees, R = Rz(rz) * Ry(ry) * Rx(rx)
inline constexpr std::uint16_t kRobotPoseRy = 44;
inline constexpr std::uint16_t kRobotPoseRz = 46;
inline constexpr std::uint16_t kRobotPoseValid = 48;  // 1: registers 36..47 hold the current pose; 0: not
inline constexpr std::uint16_t kRobotPoseSeq = 49;    // changed by the PLC for every new pose
inline constexpr std::uint16_t kRobotPoseBegin = 36;
inline constexpr std::uint16_t kRobotPoseEnd = 50;

// --- Job extras: written by mfcd, read-only (map version 3) -------------------------------
inline constexpr std::uint16_t kPickRank = 50;       // rank of the pick in 20..33 in its job's order, 0 = first choice
inline constexpr std::uint16_t kPicksLeft = 51;      // further picks NEXT can still publish for this job
inline constexpr std::uint16_t kSnapshotCount = 52;  // snapshots saved since mfcd started, wraps at 65535
inline constexpr std::uint16_t kSoftwareVersion = 53;  // mfcd's release: major << 8 | minor
inline constexpr std::uint16_t kSoftwarePatch = 54;    // mfcd's release: patch

// --- Second look: written by mfcd, read-only (map version 4) -------------------------------
// Eye-in-hand: the result in the registers asks the robot to take the camera to a second
// pose (STATUS kLookWanted); LOOK then fuses a frame set taken there with the first one.
inline constexpr std::uint16_t kLookReason = 55;  // see LookReason; 0 while kLookWanted is clear
// The flange pose in the robot base frame to take the second look from: float32 pairs in the
// configured word order like PICK_X..PICK_RZ; 0.0 while kLookWanted is clear.
inline constexpr std::uint16_t kLookX = 56;  // mm
inline constexpr std::uint16_t kLookY = 58;
inline constexpr std::uint16_t kLookZ = 60;
inline constexpr std::uint16_t kLookRx = 62;  // degrees, R = Rz(rz) * Ry(ry) * Rx(rx)
inline constexpr std::uint16_t kLookRy = 64;
inline constexpr std::uint16_t kLookRz = 66;

// --- Gripper check: written by mfcd, read-only (map version 5) ----------------------------
// The result of a CHECK_GRIP job: how the part of the checked job's pick sits in the gripper,
// seen by the gripper camera (fixed to the tool). All 0 in every other result.
inline constexpr std::uint16_t kGripState = 68;  // see GripState
// The job whose pick was checked (JOB_ID_ECHO when CHECK_GRIP was taken); 0 with GRIP_STATE 0.
inline constexpr std::uint16_t kGripOfJob = 69;
// The measured pose of the part in the tool frame (tool_T_part): float32 pairs in the configured
// word order like PICK_X..PICK_RZ; 0.0 unless GRIP_STATE is Expected or PoseError.
inline constexpr std::uint16_t kGripX = 70;  // mm
inline constexpr std::uint16_t kGripY = 72;
inline constexpr std::uint16_t kGripZ = 74;
inline constexpr std::uint16_t kGripRx = 76;  // degrees, R = Rz(rz) * Ry(ry) * Rx(rx)
inline constexpr std::uint16_t kGripRy = 78;
inline constexpr std::uint16_t kGripRz = 80;
// Measured vs ideal tool_T_part: distance of the part origins (mm) and angle of the relative
// rotation (degrees), float32; 0.0 unless GRIP_STATE is Expected or PoseError.
inline constexpr std::uint16_t kGripTranslationError = 82;
inline constexpr std::uint16_t kGripRotationError = 84;
// 86..95 reserved, read 0.

// TRIGGER and SAVE_SCENE start a job (SAVE_SCENE also saves its frame set as a snapshot);
// NEXT publishes the job's next pick at once, without a new capture; LOOK starts a job that
// takes a second frame set at the robot's current pose and fuses it with the first look of
// the job in JOB_ID_ECHO (accepted only while that result has kLookWanted); CHECK_GRIP starts a
// job that checks the part in the gripper after the robot took the pick of the job in
// JOB_ID_ECHO (accepted only while that result has kPickValid).
enum class Command : std::uint16_t {
  None = 0,
  Trigger = 1,
  Reset = 2,
  Next = 3,
  SaveScene = 4,
  Look = 5,
  CheckGrip = 6
};
// What the robot made of a published pick (PICK_RESULT). Anything but Ok counts as a failed
// pick, and mfcd keeps a snapshot of the job's frame set.
enum class PickOutcome : std::uint16_t { None = 0, Ok = 1, Missed = 2, Unreachable = 3, Collision = 4, Dropped = 5 };
inline constexpr std::uint16_t kPickOutcomeMax = 5;
// Why a result asks for a second look (LOOK_REASON).
enum class LookReason : std::uint16_t {
  None = 0,
  Always = 1,     // the configuration asks for a second look on every job
  Ambiguous = 2,  // the best candidate is ambiguous
  LowScore = 3,   // the best candidate scored below pick.min_score
};
// What the gripper check found (GRIP_STATE).
enum class GripState : std::uint16_t {
  None = 0,        // not a CHECK_GRIP result
  Expected = 1,    // the part sits in the gripper as the pick meant it to (within mfcd's tolerances)
  PoseError = 2,   // the part is in the gripper at another pose: kGripX..kGripRz hold it
  NotGrasped = 3,  // the part is not in the gripper
};
enum class Mode : std::uint16_t { Pick = 0, CountOnly = 1 };
inline constexpr std::uint16_t kModeMax = 1;

enum StatusBit : std::uint16_t {
  kReady = 1u << 0,      // a TRIGGER would be accepted now
  kBusy = 1u << 1,       // a job was accepted and its result is not published yet
  kDone = 1u << 2,       // JOB_ID_ECHO equals the last accepted job id and the result is valid to read
  kError = 1u << 3,      // ERROR_CODE != 0; send RESET to clear
  kPickValid = 1u << 4,  // the pick registers hold a pick for JOB_ID_ECHO
  kVisionOk = 1u << 5,   // the daemon reports its camera and vision pipeline healthy
  // The result of JOB_ID_ECHO asks for a second look (map version 4): kLookX..kLookRz hold the
  // flange pose to take it from, and kPickValid is clear.
  kLookWanted = 1u << 6,
};

}  // namespace mfcd::motion::reg
