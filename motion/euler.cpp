#include "motion/euler.hpp"

#include <cmath>
#include <numbers>

namespace mfcd::motion {

namespace {
constexpr double kDeg = 180.0 / std::numbers::pi;
// Below this cos(ry) the rx/rz split is numerically meaningless (ry within ~0.0006 deg of ±90).
constexpr double kGimbalCos = 1e-8;
}  // namespace

Eigen::Matrix3d euler_to_rotation(const EulerXYZ& a) noexcept {
  const double x = a.rx_deg / kDeg, y = a.ry_deg / kDeg, z = a.rz_deg / kDeg;
  const double cx = std::cos(x), sx = std::sin(x);
  const double cy = std::cos(y), sy = std::sin(y);
  const double cz = std::cos(z), sz = std::sin(z);
  Eigen::Matrix3d r;
  r << cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx, sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx,
      -sy, cy * sx, cy * cx;
  return r;
}

EulerXYZ rotation_to_euler(const Eigen::Matrix3d& r) noexcept {
  EulerXYZ out;
  const double cy = std::hypot(r(0, 0), r(1, 0));
  out.ry_deg = std::atan2(-r(2, 0), cy) * kDeg;
  if (cy > kGimbalCos) {
    out.rx_deg = std::atan2(r(2, 1), r(2, 2)) * kDeg;
    out.rz_deg = std::atan2(r(1, 0), r(0, 0)) * kDeg;
  } else {
    // ry = ±90: r(0,1) = -sin(rz ∓ rx), r(1,1) = cos(rz ∓ rx); choose rx = 0.
    out.rx_deg = 0.0;
    out.rz_deg = std::atan2(-r(0, 1), r(1, 1)) * kDeg;
  }
  // atan2 gives [-180, 180]; map -180 to 180 so the ranges are half-open as documented.
  if (out.rx_deg == -180.0) out.rx_deg = 180.0;
  if (out.rz_deg == -180.0) out.rz_deg = 180.0;
  return out;
}

}  // namespace mfcd::motion
