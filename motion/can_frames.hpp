// Classic CAN (8-byte) frames of the robot link, laid out as docs/mfcd.dbc describes:
// little-endian (Intel) signals, 11-bit identifiers relative to a configurable base.
//
//   base+0x00 MFCD_Status     status bits, job id echo, error code, objects remaining
//   base+0x01 MFCD_Heartbeat  heartbeat counter, cycle time, recipe echo, candidates
//   base+0x02 MFCD_Version    mfcd's release (major, minor, patch), register map and DBC versions
//   base+0x10 MFCD_PickA      PickSeq, X, Y, candidate index
//   base+0x11 MFCD_PickB      PickSeq, Z, Rx, Ry
//   base+0x12 MFCD_PickC      PickSeq, Rz, score, job id, valid, rank  (sent last: completes the pick)
//
// Classic CAN rather than CAN FD because every PLC CAN module and robot controller speaks
// it; the pose is split over three frames that carry the same PickSeq, so a receiver can
// tell a complete pick from frames of two different picks.
#pragma once

#include "motion/robot_report.hpp"

#include <linux/can.h>

#include <array>
#include <cstdint>
#include <optional>

namespace mfcd::motion {

inline constexpr canid_t kCanDefaultBase = 0x180;
inline constexpr canid_t kCanStatusOffset = 0x00;
inline constexpr canid_t kCanHeartbeatOffset = 0x01;
inline constexpr canid_t kCanVersionOffset = 0x02;
inline constexpr canid_t kCanPickAOffset = 0x10;
inline constexpr canid_t kCanPickBOffset = 0x11;
inline constexpr canid_t kCanPickCOffset = 0x12;

inline constexpr double kCanMmPerBit = 0.01;   // X, Y, Z: signed 24 bit, ±83886.07 mm
inline constexpr double kCanDegPerBit = 0.01;  // Rx, Ry, Rz: signed 16 bit, ±327.67 deg
inline constexpr double kCanScorePerBit = 0.0001;

// Layout version of docs/mfcd.dbc, the N of its VERSION "mfcd robot link N", sent in
// MFCD_Version so a receiver can tell whether its copy of the DBC describes these frames.
// Raised with every change of a frame or signal.
inline constexpr std::uint8_t kCanDbcVersion = 4;

// Status word bits on CAN (bytes 0-1 of MFCD_Status): the Modbus READY/ERROR/PICK_VALID/VISION_OK
// bits (register_map.hpp), one DBC signal each. BUSY and DONE belong to the Modbus job handshake and
// are not sent; they and bits 6-15 are 0 (reserved signals in the DBC).
std::uint16_t can_status_word(const RobotReport& report) noexcept;

can_frame encode_status(const RobotReport& report, canid_t base) noexcept;
can_frame encode_heartbeat(std::uint16_t heartbeat, const RobotReport& report, canid_t base) noexcept;
// mfcd's release in the packing of Modbus registers 53..54: software_version = major << 8 | minor,
// software_patch = patch. The frame also carries reg::kMapVersion and kCanDbcVersion.
can_frame encode_version(std::uint16_t software_version, std::uint16_t software_patch, canid_t base) noexcept;
// Nullopt when a coordinate does not fit its signal (|x| > 83886.07 mm, |angle| > 327.67
// deg, NaN): the pick is then not sent rather than sent wrong.
std::optional<std::array<can_frame, 3>> encode_pick(const RobotReport& report, std::uint8_t sequence,
                                                    canid_t base) noexcept;

// Decoded pick, for receivers and tests.
struct CanPick {
  std::uint8_t sequence = 0;
  PickPose pose;
  float score = 0;
  std::uint16_t job_id = 0;
  std::uint8_t candidate_index = 0;
  std::uint8_t rank = 0;  // rank of the pick in its job's order (Modbus PICK_RANK), saturates at 127
  bool valid = false;
};
// Nullopt unless the three frames have the right ids and the same sequence counter.
std::optional<CanPick> decode_pick(const std::array<can_frame, 3>& frames, canid_t base) noexcept;

// Decoded MFCD_Version, for receivers and tests.
struct CanVersion {
  std::uint8_t major = 0;
  std::uint8_t minor = 0;
  std::uint16_t patch = 0;
  std::uint8_t map_version = 0;  // Modbus register map version (reg::kMapVersion)
  std::uint8_t dbc_version = 0;  // kCanDbcVersion of the sender
};
// Nullopt unless the frame has the version id for `base` and 8 bytes.
std::optional<CanVersion> decode_version(const can_frame& frame, canid_t base) noexcept;

// What an error frame (CAN_ERR_FLAG set) says about the controller.
enum class CanErrorKind { Other, BusOff, ErrorPassive, Restarted };
CanErrorKind classify_error_frame(const can_frame& frame) noexcept;

}  // namespace mfcd::motion
