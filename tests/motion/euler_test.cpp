#include "motion/euler.hpp"
#include "motion/pick_transform.hpp"

#include <gtest/gtest.h>

#include <numbers>
#include <random>

using namespace mfcd::motion;

namespace {
constexpr double kRad = std::numbers::pi / 180.0;

// Obviously-right twin: compose elementary rotations, fixed axes X then Y then Z.
Eigen::Matrix3d reference_rotation(double rx, double ry, double rz) {
  return (Eigen::AngleAxisd(rz * kRad, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(ry * kRad, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(rx * kRad, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}
}  // namespace

TEST(Euler, MatchesComposedElementaryRotations) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> angle(-360.0, 360.0);
  for (int i = 0; i < 10000; ++i) {
    const double rx = angle(rng), ry = angle(rng), rz = angle(rng);
    ASSERT_TRUE(euler_to_rotation({rx, ry, rz}).isApprox(reference_rotation(rx, ry, rz), 1e-12));
  }
}

TEST(Euler, ExtrinsicXYZMeaning) {
  // rx = 90 alone turns base Y into base Z.
  EXPECT_TRUE((euler_to_rotation({90, 0, 0}) * Eigen::Vector3d::UnitY()).isApprox(Eigen::Vector3d::UnitZ(), 1e-12));
  // rx = 90 then (fixed) rz = 90: Y -> Z -> Z (rz leaves Z alone); X -> X -> Y.
  const Eigen::Matrix3d r = euler_to_rotation({90, 0, 90});
  EXPECT_TRUE((r * Eigen::Vector3d::UnitY()).isApprox(Eigen::Vector3d::UnitZ(), 1e-12));
  EXPECT_TRUE((r * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY(), 1e-12));
}

TEST(Euler, RoundTripInCanonicalRange) {
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> full(-179.999, 180.0), half(-89.99, 89.99);
  for (int i = 0; i < 20000; ++i) {
    const EulerXYZ in{full(rng), half(rng), full(rng)};
    const EulerXYZ out = rotation_to_euler(euler_to_rotation(in));
    ASSERT_NEAR(out.rx_deg, in.rx_deg, 1e-7);
    ASSERT_NEAR(out.ry_deg, in.ry_deg, 1e-7);
    ASSERT_NEAR(out.rz_deg, in.rz_deg, 1e-7);
  }
}

TEST(Euler, AnyAnglesGiveTheSameRotationBack) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> angle(-720.0, 720.0);
  for (int i = 0; i < 20000; ++i) {
    const Eigen::Matrix3d r = euler_to_rotation({angle(rng), angle(rng), angle(rng)});
    const EulerXYZ e = rotation_to_euler(r);
    ASSERT_GE(e.ry_deg, -90.0);
    ASSERT_LE(e.ry_deg, 90.0);
    ASSERT_GT(e.rx_deg, -180.0);
    ASSERT_LE(e.rx_deg, 180.0);
    ASSERT_GT(e.rz_deg, -180.0);
    ASSERT_LE(e.rz_deg, 180.0);
    ASSERT_TRUE(euler_to_rotation(e).isApprox(r, 1e-9));
  }
}

TEST(Euler, GimbalLock) {
  for (double ry : {90.0, -90.0})
    for (double rx : {-170.0, -30.0, 0.0, 45.0, 179.0})
      for (double rz : {-120.0, 0.0, 10.0, 180.0}) {
        const Eigen::Matrix3d r = euler_to_rotation({rx, ry, rz});
        const EulerXYZ e = rotation_to_euler(r);
        EXPECT_EQ(e.rx_deg, 0.0) << "rx folded into rz at gimbal lock";
        EXPECT_NEAR(e.ry_deg, ry, 1e-6);
        EXPECT_TRUE(euler_to_rotation(e).isApprox(r, 1e-9)) << rx << " " << ry << " " << rz;
        // ry = +90: only rz - rx is defined; ry = -90: only rz + rx.
        const double defined = ry > 0 ? rz - rx : rz + rx;
        const double diff = std::remainder(e.rz_deg - defined, 360.0);
        EXPECT_NEAR(diff, 0.0, 1e-6);
      }
  // Just off the lock the split is still recovered as a valid rotation.
  for (double eps : {1e-3, 1e-5, 1e-7}) {
    const Eigen::Matrix3d r = euler_to_rotation({20.0, 90.0 - eps, -35.0});
    EXPECT_TRUE(euler_to_rotation(rotation_to_euler(r)).isApprox(r, 1e-8)) << eps;
  }
}

TEST(Euler, AgreesWithEigenEulerAngles) {
  // Eigen's eulerAngles(2, 1, 0) is the same convention with other ranges; compare rotations.
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> angle(-180.0, 180.0);
  for (int i = 0; i < 5000; ++i) {
    const Eigen::Matrix3d r = euler_to_rotation({angle(rng), angle(rng) / 2, angle(rng)});
    const Eigen::Vector3d zyx = r.eulerAngles(2, 1, 0) / kRad;
    const EulerXYZ mine = rotation_to_euler(r);
    ASSERT_TRUE(reference_rotation(zyx[2], zyx[1], zyx[0]).isApprox(euler_to_rotation(mine), 1e-9));
  }
}
