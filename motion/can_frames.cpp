#include "motion/can_frames.hpp"

#include "motion/register_map.hpp"

#include <linux/can/error.h>

#include <algorithm>
#include <cmath>

namespace mfcd::motion {

namespace {

void put_le(can_frame& f, unsigned byte, unsigned bytes, std::uint32_t value) noexcept {
  for (unsigned i = 0; i < bytes; ++i) f.data[byte + i] = static_cast<std::uint8_t>(value >> (8 * i));
}

std::uint32_t get_le(const can_frame& f, unsigned byte, unsigned bytes) noexcept {
  std::uint32_t v = 0;
  for (unsigned i = 0; i < bytes; ++i) v |= static_cast<std::uint32_t>(f.data[byte + i]) << (8 * i);
  return v;
}

std::int32_t sign_extend(std::uint32_t v, unsigned bits) noexcept {
  const std::uint32_t sign = 1u << (bits - 1);
  return static_cast<std::int32_t>((v ^ sign) - sign);
}

// Physical value -> raw signed integer of `bits`, rounded; nullopt when out of range.
std::optional<std::uint32_t> scaled(double value, double per_bit, unsigned bits) noexcept {
  if (!std::isfinite(value)) return std::nullopt;
  const double raw = std::nearbyint(value / per_bit);
  const double limit = static_cast<double>(1u << (bits - 1));
  if (raw < -limit || raw > limit - 1) return std::nullopt;
  return static_cast<std::uint32_t>(static_cast<std::int32_t>(raw)) & ((bits == 32) ? ~0u : ((1u << bits) - 1));
}

can_frame frame(canid_t id) noexcept {
  can_frame f{};
  f.can_id = id;
  f.len = 8;
  return f;
}

}  // namespace

std::uint16_t can_status_word(const RobotReport& r) noexcept {
  std::uint16_t s = 0;
  if (r.ready && r.error_code == 0) s |= reg::kReady;
  if (r.error_code != 0) s |= reg::kError;
  if (r.pick_valid) s |= reg::kPickValid;
  if (r.vision_ok) s |= reg::kVisionOk;
  return s;
}

can_frame encode_status(const RobotReport& r, canid_t base) noexcept {
  can_frame f = frame(base + kCanStatusOffset);
  put_le(f, 0, 2, can_status_word(r));
  put_le(f, 2, 2, r.job_id);
  put_le(f, 4, 2, r.error_code);
  put_le(f, 6, 2, r.objects_remaining);
  return f;
}

can_frame encode_heartbeat(std::uint16_t heartbeat, const RobotReport& r, canid_t base) noexcept {
  can_frame f = frame(base + kCanHeartbeatOffset);
  put_le(f, 0, 2, heartbeat);
  put_le(f, 2, 2, r.cycle_time_ms);
  put_le(f, 4, 2, r.recipe_id);
  put_le(f, 6, 1, std::min<std::uint16_t>(r.candidate_count, 255));
  put_le(f, 7, 1, reg::kMapVersion);
  return f;
}

can_frame encode_version(std::uint16_t software_version, std::uint16_t software_patch, canid_t base) noexcept {
  can_frame f = frame(base + kCanVersionOffset);
  put_le(f, 0, 1, software_version >> 8u);    // major
  put_le(f, 1, 1, software_version & 0xffu);  // minor
  put_le(f, 2, 2, software_patch);
  put_le(f, 4, 1, reg::kMapVersion);
  put_le(f, 5, 1, kCanDbcVersion);
  return f;  // bytes 6-7 reserved: 0
}

std::optional<std::array<can_frame, 3>> encode_pick(const RobotReport& r, std::uint8_t sequence,
                                                    canid_t base) noexcept {
  const auto x = scaled(r.pick.x_mm, kCanMmPerBit, 24);
  const auto y = scaled(r.pick.y_mm, kCanMmPerBit, 24);
  const auto z = scaled(r.pick.z_mm, kCanMmPerBit, 24);
  const auto rx = scaled(r.pick.rx_deg, kCanDegPerBit, 16);
  const auto ry = scaled(r.pick.ry_deg, kCanDegPerBit, 16);
  const auto rz = scaled(r.pick.rz_deg, kCanDegPerBit, 16);
  if (!x || !y || !z || !rx || !ry || !rz || !std::isfinite(r.score)) return std::nullopt;
  const double score = std::clamp<double>(r.score, 0.0, 1.0);
  const auto score_raw = static_cast<std::uint32_t>(std::nearbyint(score / kCanScorePerBit));

  std::array<can_frame, 3> out{frame(base + kCanPickAOffset), frame(base + kCanPickBOffset),
                               frame(base + kCanPickCOffset)};
  for (can_frame& f : out) f.data[0] = sequence;
  put_le(out[0], 1, 3, *x);
  put_le(out[0], 4, 3, *y);
  put_le(out[0], 7, 1, std::min<std::uint16_t>(r.candidate_index, 255));
  put_le(out[1], 1, 3, *z);
  put_le(out[1], 4, 2, *rx);
  put_le(out[1], 6, 2, *ry);
  put_le(out[2], 1, 2, *rz);
  put_le(out[2], 3, 2, score_raw);
  put_le(out[2], 5, 2, r.job_id);
  out[2].data[7] =
      static_cast<std::uint8_t>((r.pick_valid ? 1u : 0u) | (std::min<std::uint16_t>(r.pick_rank, 127) << 1));
  return out;
}

std::optional<CanPick> decode_pick(const std::array<can_frame, 3>& f, canid_t base) noexcept {
  if (f[0].can_id != base + kCanPickAOffset || f[1].can_id != base + kCanPickBOffset ||
      f[2].can_id != base + kCanPickCOffset || f[0].len != 8 || f[1].len != 8 || f[2].len != 8)
    return std::nullopt;
  if (f[0].data[0] != f[1].data[0] || f[1].data[0] != f[2].data[0]) return std::nullopt;
  CanPick p;
  p.sequence = f[0].data[0];
  p.pose.x_mm = static_cast<float>(sign_extend(get_le(f[0], 1, 3), 24) * kCanMmPerBit);
  p.pose.y_mm = static_cast<float>(sign_extend(get_le(f[0], 4, 3), 24) * kCanMmPerBit);
  p.candidate_index = f[0].data[7];
  p.pose.z_mm = static_cast<float>(sign_extend(get_le(f[1], 1, 3), 24) * kCanMmPerBit);
  p.pose.rx_deg = static_cast<float>(sign_extend(get_le(f[1], 4, 2), 16) * kCanDegPerBit);
  p.pose.ry_deg = static_cast<float>(sign_extend(get_le(f[1], 6, 2), 16) * kCanDegPerBit);
  p.pose.rz_deg = static_cast<float>(sign_extend(get_le(f[2], 1, 2), 16) * kCanDegPerBit);
  p.score = static_cast<float>(get_le(f[2], 3, 2) * kCanScorePerBit);
  p.job_id = static_cast<std::uint16_t>(get_le(f[2], 5, 2));
  p.valid = (f[2].data[7] & 1u) != 0;
  p.rank = static_cast<std::uint8_t>(f[2].data[7] >> 1);
  return p;
}

std::optional<CanVersion> decode_version(const can_frame& f, canid_t base) noexcept {
  if (f.can_id != base + kCanVersionOffset || f.len != 8) return std::nullopt;
  CanVersion v;
  v.major = f.data[0];
  v.minor = f.data[1];
  v.patch = static_cast<std::uint16_t>(get_le(f, 2, 2));
  v.map_version = f.data[4];
  v.dbc_version = f.data[5];
  return v;
}

CanErrorKind classify_error_frame(const can_frame& f) noexcept {
  if (!(f.can_id & CAN_ERR_FLAG)) return CanErrorKind::Other;
  if (f.can_id & CAN_ERR_BUSOFF) return CanErrorKind::BusOff;
  if (f.can_id & CAN_ERR_RESTARTED) return CanErrorKind::Restarted;
  if ((f.can_id & CAN_ERR_CRTL) && (f.data[1] & (CAN_ERR_CRTL_TX_PASSIVE | CAN_ERR_CRTL_RX_PASSIVE)))
    return CanErrorKind::ErrorPassive;
  return CanErrorKind::Other;
}

}  // namespace mfcd::motion
