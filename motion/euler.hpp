// Euler angles as robot controllers report them.
//
// Convention (the one FANUC W,P,R and KUKA A,B,C use): rx, ry, rz in degrees with
//     R = Rz(rz) * Ry(ry) * Rx(rx)
// i.e. extrinsic X-Y-Z (rotate about the fixed base X by rx, then fixed Y by ry, then fixed
// Z by rz), which is the same rotation as intrinsic Z-Y'-X''. KUKA's A = rz, B = ry, C = rx.
//
// Canonical ranges returned by rotation_to_euler(): rx, rz in (-180, 180], ry in [-90, 90].
// At gimbal lock (|ry| = 90) only rz - rx (ry = +90) or rz + rx (ry = -90) is defined; the
// function then reports rx = 0 and puts the whole angle into rz.
#pragma once

#include <Eigen/Geometry>

namespace mfcd::motion {

struct EulerXYZ {
  double rx_deg = 0, ry_deg = 0, rz_deg = 0;
};

Eigen::Matrix3d euler_to_rotation(const EulerXYZ& angles) noexcept;
EulerXYZ rotation_to_euler(const Eigen::Matrix3d& rotation) noexcept;

}  // namespace mfcd::motion
