// Eye-in-hand picking end to end: the real daemon (test vision backend: the simulated bin's ground
// truth) with the camera on the flange. The PLC writes the robot pose block before each TRIGGER;
// the published pick must be base_T_flange * flange_T_camera * cam_T_part, computed here by
// explicit matrix products, and a TRIGGER without a valid pose must end with ERROR_CODE 8.
#include <gtest/gtest.h>

#include <modbus/modbus.h>

#include <Eigen/Geometry>
#include <cmath>

#include "daemon_fixture.hpp"
#include "daemon_process.hpp"
#include "motion/float_codec.hpp"
#include "motion/register_map.hpp"
#include "plc_test_client.hpp"

using namespace mfcd::daemon::test;
using namespace mfcd::motion;

namespace {

constexpr double kFlangeToCamera[6] = {10, -20, 150, 0, 0, 90};  // flange_T_camera of the configuration

std::string eye_in_hand_config(const fs::path& dir) {
  std::string c = sim_cell_config(dir, 2000);
  const std::string eye_to_hand =
      "hand_eye:\n  base_T_camera: {x_mm: 500, y_mm: 0, z_mm: 800, rx_deg: 180, ry_deg: 0, rz_deg: 0}\n";
  const auto at = c.find(eye_to_hand);
  if (at == std::string::npos) return "";
  return c.replace(at, eye_to_hand.size(),
                   "hand_eye:\n  setup: eye_in_hand\n"
                   "  flange_T_camera: {x_mm: 10, y_mm: -20, z_mm: 150, rx_deg: 0, ry_deg: 0, rz_deg: 90}\n");
}

}  // namespace

class EyeInHand : public DaemonFixture {};

TEST_F(EyeInHand, PickIsTransformedWithTheRobotPoseOfItsCapture) {
  ASSERT_FALSE(eye_in_hand_config("/tmp").empty()) << "simCellConfig's hand_eye changed";
  start_daemon_on("eye-in-hand", eye_in_hand_config);
  if (IsSkipped() || HasFailure()) return;
  DaemonProcess& proc = *this->proc_;
  Client plc(proc.modbus_port());
  ASSERT_TRUE(plc.connected);
  ASSERT_TRUE(plc.wait_ready());
  Regs r;

  // No pose written yet: the job ends with ERROR_CODE 8, no pick.
  ASSERT_EQ(plc.trigger(1, 0), 0);
  ASSERT_TRUE(plc.wait_for(1, r)) << proc.log();
  EXPECT_EQ(r.at(reg::kErrorCode), 8);
  EXPECT_FALSE(r.at(reg::kStatus) & reg::kPickValid);
  const std::uint16_t reset = 2;
  ASSERT_EQ(modbus_write_registers(plc.ctx, reg::kCommand, 1, &reset), 1);

  const Eigen::Isometry3d flange_T_camera = pose_of(kFlangeToCamera[0], kFlangeToCamera[1], kFlangeToCamera[2],
                                                    kFlangeToCamera[3], kFlangeToCamera[4], kFlangeToCamera[5]);
  const double views[2][6] = {{400, 50, 600, 180, 0, 30}, {520, -80, 640, 175, 4, -60}};
  for (int v = 0; v < 2; ++v) {
    const std::uint16_t job = static_cast<std::uint16_t>(10 + v);
    ASSERT_EQ(write_robot_pose(plc.ctx, views[v], 1, static_cast<std::uint16_t>(v + 1)), 14);
    ASSERT_TRUE(plc.wait_ready());
    ASSERT_EQ(plc.trigger(job, 0), 0);
    ASSERT_TRUE(plc.wait_for(job, r)) << proc.log();
    ASSERT_EQ(r.at(reg::kErrorCode), 0) << proc.log();
    ASSERT_TRUE(r.at(reg::kStatus) & reg::kPickValid);
    const json last = proc.ctl({{"cmd", "last"}})["result"];
    EXPECT_NEAR(last["robot_pose"]["x"].get<double>(), views[v][0], 1e-3);
    EXPECT_NEAR(last["robot_pose"]["rz"].get<double>(), views[v][5], 1e-3);
    // The chosen candidate's camera-frame pose, through the flange pose this job was given.
    const json& c = last["candidates"][last["chosen"].get<int>()];
    Eigen::Isometry3d cam_T_part = Eigen::Isometry3d::Identity();
    for (int i = 0; i < 9; ++i) cam_T_part.linear()(i / 3, i % 3) = c["R_cam"][i].get<double>();
    for (int i = 0; i < 3; ++i) cam_T_part.translation()(i) = c["t_cam_mm"][i].get<double>();
    const Eigen::Isometry3d base_T_flange =
        pose_of(views[v][0], views[v][1], views[v][2], views[v][3], views[v][4], views[v][5]);
    const Eigen::Vector3d expect = (base_T_flange * flange_T_camera * cam_T_part).translation();
    EXPECT_NEAR(r.f(reg::kPickX), expect.x(), 0.01) << "view " << v;
    EXPECT_NEAR(r.f(reg::kPickY), expect.y(), 0.01) << "view " << v;
    EXPECT_NEAR(r.f(reg::kPickZ), expect.z(), 0.01) << "view " << v;
  }

  // ROBOT_POSE_VALID 0 (the robot is moving): refused again.
  ASSERT_EQ(write_robot_pose(plc.ctx, views[0], 0, 3), 14);
  ASSERT_EQ(plc.trigger(20, 0), 0);
  ASSERT_TRUE(plc.wait_for(20, r)) << proc.log();
  EXPECT_EQ(r.at(reg::kErrorCode), 8);
  proc.signal(SIGTERM);
  EXPECT_EQ(proc.wait(15000), 0);
}

TEST(EyeInHandConfig, ConfigurationRulesNameTheKey) {
  DaemonProcess proc("eye-in-hand-config");
  std::string config = eye_in_hand_config(proc.dir());
  ASSERT_FALSE(config.empty());
  const auto check = [&](const std::string& text, const std::string& expect) {
    proc.write_config(text);
    proc.start(MFCD_TEST_DAEMON, {"--check-config"});
    EXPECT_EQ(proc.wait(20000), 2) << text;
    EXPECT_NE(proc.log().find(expect), std::string::npos) << proc.log();
  };
  proc.write_config(config);
  proc.start(MFCD_TEST_DAEMON, {"--check-config"});
  EXPECT_EQ(proc.wait(20000), 0) << proc.log();
  // Continuous mode has no capture the PLC could give a pose for.
  std::string continuous = config;
  continuous.replace(continuous.find("daemon:\n"), 8, "daemon:\n  mode: continuous\n");
  check(continuous, "hand_eye.setup");
  // The eye-to-hand key with the eye-in-hand setup.
  std::string both = config;
  both.replace(both.find("  flange_T_camera:"), 0, "  base_T_camera: {x_mm: 1}\n");
  check(both, "hand_eye.base_T_camera");
}
