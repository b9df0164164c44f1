// Calibration through the daemon, end to end: the real daemon process (mfcd with the test vision
// backend; calibration never touches the vision stage) on a simulated cell that shows a
// checkerboard plate, driven by the real mfcd-ctl. Intrinsics and both hand-eye set-ups run to
// completion and must recover the simulated cell's truth (fx fy cx cy within 0.5 %, hand-eye
// within 0.5 mm and 0.1 deg); bad input (too few views, no board in view, degenerate motion,
// apply without confirmation) gives a clear error and leaves the camera file byte-identical.
// The robot pose also comes from the PLC: a real libmodbus client writes the map-v2 pose block.
#include <gtest/gtest.h>
#include <modbus/modbus.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <random>

#include "daemon_process.hpp"
#include "motion/float_codec.hpp"
#include "motion/register_map.hpp"
#include "vision/calib/sim_board.hpp"
#include "vision/camera/camera.hpp"

using namespace mfcd::daemon::test;
namespace calib = mfcd::vision::calib;
namespace reg = mfcd::motion::reg;

namespace {

// The simulated cell's true transforms (written into its configuration below).
constexpr double kEyeToHandCamera[6] = {620.0, 110.0, 950.0, 178.0, 1.0, -88.0};  // base_T_camera
constexpr double kEyeToHandPlate[6] = {-35.0, -20.0, 25.0, 0.5, -1.0, 30.0};      // flange_T_plate
constexpr double kEyeInHandCamera[6] = {42.0, -27.5, 95.0, 1.5, -2.0, 90.5};      // flange_T_camera
constexpr double kEyeInHandPlate[6] = {450.0, -60.0, 15.0, 180.0, 0.0, 12.0};     // base_T_plate

std::string yaml_pose(const double p[6]) {
  char s[200];
  std::snprintf(s, sizeof s, "{x_mm: %g, y_mm: %g, z_mm: %g, rx_deg: %g, ry_deg: %g, rz_deg: %g}", p[0], p[1], p[2],
                p[3], p[4], p[5]);
  return s;
}
cv::Matx44d matrix(const double p[6]) { return calib::RobotPose{p[0], p[1], p[2], p[3], p[4], p[5]}.matrix(); }

std::string config(const fs::path& dir, const fs::path& camera_file) {
  std::ostringstream s;
  s << "daemon:\n  cycle_budget_ms: 2000\n  control_socket: " << (dir / "ctl.sock").string()
    << "\n  lock_memory: false\n  realtime_priority: 0\n"
    << "camera:\n  model: " << camera_file.string() << "\n"
    << "simulation:\n  calibration_plate:\n"
    << "    eye_to_hand:\n      base_T_camera: " << yaml_pose(kEyeToHandCamera)
    << "\n      flange_T_plate: " << yaml_pose(kEyeToHandPlate)
    << "\n    eye_in_hand:\n      flange_T_camera: " << yaml_pose(kEyeInHandCamera)
    << "\n      base_T_plate: " << yaml_pose(kEyeInHandPlate) << "\nrecipes:\n  - {id: 0, part: any, obj_id: 0}\n"
    << "calibration:\n  board: 9x6\n  square_mm: 10\n"
    << "modbus:\n  bind_address: 127.0.0.1\n  port: 0\n"
    << "snapshots:\n  directory: " << (dir / "snapshots").string() << "\n  on_failure: false\n";
  return s.str();
}

std::string bytes(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string pose_arg(const calib::RobotPose& p) {
  char s[200];
  std::snprintf(s, sizeof s, "%.3f,%.3f,%.3f,%.3f,%.3f,%.3f", p.x_mm, p.y_mm, p.z_mm, p.rx_deg, p.ry_deg, p.rz_deg);
  return s;
}

// A pose as the robot controller reports it: 0.001 mm / 0.001 deg steps.
calib::RobotPose reported(const cv::Matx44d& T) {
  calib::RobotPose p = calib::RobotPose::from_matrix(T);
  for (double* v : {&p.x_mm, &p.y_mm, &p.z_mm, &p.rx_deg, &p.ry_deg, &p.rz_deg}) *v = std::round(*v * 1000) / 1000;
  return p;
}

struct CtlResult {
  int exit = -1;
  std::string text;  // everything mfcd-ctl printed
  json answer;       // the JSON answer it printed last
};

class CalibrationE2E : public ::testing::Test {
 protected:
  void SetUp() override {
    proc_ = std::make_unique<DaemonProcess>("calib");
    start(proc_->dir());
  }

  // The daemon, its camera file in `camera_dir` (a copy of the simulated camera's).
  void start(const fs::path& camera_dir) {
    camera_file_ = camera_dir / "camera.yaml";
    fs::copy_file(MFC_SOURCE_DIR "/config/camera-sim.yaml", camera_file_);
    proc_->write_config(config(proc_->dir(), camera_file_));
    proc_->start(MFCD_TEST_DAEMON);
    if (!proc_->wait_ready()) {
      const std::string log = proc_->log();
      if (log.find("EGL") != std::string::npos || log.find("OpenGL") != std::string::npos)
        GTEST_SKIP() << "no offscreen OpenGL: " << log;
      FAIL() << "mfcd did not become ready:\n" << log;
    }
    truth_ = mfcd::vision::load_camera_config(camera_file_);
    original_ = bytes(camera_file());
  }

  const fs::path& camera_file() const { return camera_file_; }

  // Runs the real mfcd-ctl with stdin from /dev/null (no terminal to ask on).
  CtlResult ctl(const std::string& args) const {
    const std::string cmd =
        std::string(MFCD_CTL) + " -s " + proc_->socket().string() + " " + args + " < /dev/null 2>&1";
    CtlResult r;
    FILE* p = ::popen(cmd.c_str(), "r");
    char buf[4096];
    size_t n;
    while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) r.text.append(buf, n);
    const int status = ::pclose(p);
    r.exit = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    const auto at = r.text.rfind("\n{\n") != std::string::npos ? r.text.rfind("\n{\n") + 1
                    : r.text.rfind("{\n", 0) == 0              ? 0
                                                               : std::string::npos;
    if (at != std::string::npos) r.answer = json::parse(r.text.substr(at), nullptr, false);
    return r;
  }

  // Hand-eye flange poses of `count` well-spread views of the plate, for `mode` in this cell.
  std::vector<calib::RobotPose> hand_eye_poses(calib::HandEyeMode mode, int count, unsigned seed) const {
    const calib::CheckerBoard board{9, 6, 10};
    std::mt19937 rng(seed);
    const bool in_hand = mode == calib::HandEyeMode::eye_in_hand;
    const cv::Matx44d X = matrix(in_hand ? kEyeInHandCamera : kEyeToHandCamera);
    const cv::Matx44d Y = matrix(in_hand ? kEyeInHandPlate : kEyeToHandPlate);
    std::vector<calib::RobotPose> poses;
    for (const auto& T : calib::random_plate_views(truth_.camera, board, count, truth_.working_distance_mm, rng, 35.0))
      poses.push_back(reported(calib::sim_flange_pose(mode, X, Y, T)));
    return poses;
  }

  void run_hand_eye(calib::HandEyeMode mode);

  std::unique_ptr<DaemonProcess> proc_;
  fs::path camera_file_;
  mfcd::vision::CameraConfig truth_;
  std::string original_;
};

TEST_F(CalibrationE2E, IntrinsicsRecoverTheSimulatedCameraAndApplyKeepsThePreviousFile) {
  auto r = ctl("calibrate intrinsics start");
  ASSERT_EQ(r.exit, 0) << r.text;
  EXPECT_EQ(proc_->ctl({{"cmd", "status"}})["state"], "calibrating");
  // Picking is refused while the session runs.
  const json trig = proc_->ctl({{"cmd", "trigger"}});
  EXPECT_FALSE(trig["ok"]);
  EXPECT_NE(trig["error"].get<std::string>().find("calibration session"), std::string::npos) << trig.dump();

  // The bin, no plate: board not found, the view is not kept.
  r = ctl("calibrate capture");
  EXPECT_EQ(r.exit, 1) << r.text;
  EXPECT_FALSE(r.answer["board_found"]);
  EXPECT_NE(r.answer["error"].get<std::string>().find("not found"), std::string::npos) << r.text;
  EXPECT_EQ(r.answer["views"], 0);

  const calib::CheckerBoard board{9, 6, 10};
  std::mt19937 rng(7);
  const auto views = calib::random_plate_views(truth_.camera, board, 20, truth_.working_distance_mm, rng, 60, 0.7, 1.1);
  for (int i = 0; i < 2; ++i) {
    r = ctl("calibrate capture --sim-plate-pose " +
            pose_arg(calib::RobotPose::from_matrix(views[static_cast<size_t>(i)])));
    ASSERT_EQ(r.exit, 0) << r.text;
    EXPECT_TRUE(r.answer["accepted"]);
  }
  // Too few views: a clear error, nothing written, the session goes on.
  r = ctl("calibrate compute");
  EXPECT_EQ(r.exit, 1) << r.text;
  EXPECT_NE(r.text.find("views"), std::string::npos) << r.text;
  EXPECT_EQ(bytes(camera_file()), original_);

  for (size_t i = 2; i < views.size(); ++i) {
    r = ctl("calibrate capture --sim-plate-pose " + pose_arg(calib::RobotPose::from_matrix(views[i])));
    ASSERT_EQ(r.exit, 0) << r.text;
  }
  EXPECT_EQ(r.answer["views"], 20);

  // Compute runs on the calibration worker: the main loop keeps answering meanwhile.
  {
    const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::strncpy(addr.sun_path, proc_->socket().c_str(), sizeof addr.sun_path - 1);
    ASSERT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
    const std::string line = json{{"cmd", "calibrate"}, {"action", "compute"}}.dump() + "\n";
    const auto t0 = std::chrono::steady_clock::now();
    ASSERT_EQ(::send(fd, line.data(), line.size(), MSG_NOSIGNAL), static_cast<ssize_t>(line.size()));
    int status_while_working = 0, status_requests = 0;
    double slowest_status_ms = 0;
    pollfd p{fd, POLLIN, 0};
    while (::poll(&p, 1, 0) == 0) {
      const auto s0 = std::chrono::steady_clock::now();
      const json st = proc_->ctl({{"cmd", "status"}}, 5000);
      slowest_status_ms = std::max(
          slowest_status_ms, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - s0).count());
      ASSERT_TRUE(st["ok"]) << st.dump();
      ++status_requests;
      if (st["calibration"].value("working", "") == "compute") ++status_while_working;
      ASSERT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(60)) << "compute never answered";
    }
    const double compute_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    ::close(fd);
    std::printf(
        "[ figures  ] intrinsics compute took %.0f ms; %d status requests answered meanwhile, slowest %.1f ms\n",
        compute_ms, status_while_working, slowest_status_ms);
    // Every status sent before compute answered says so (the last may cross its end).
    EXPECT_GE(status_while_working, status_requests - 1) << "status was not answered while compute ran";
    EXPECT_LT(slowest_status_ms, 250) << "the main loop waited for compute";
  }
  r = ctl("calibrate compute");
  ASSERT_EQ(r.exit, 0) << r.text;
  const json k = r.answer["intrinsics"];
  const double fx = k["fx"], fy = k["fy"], cx = k["cx"], cy = k["cy"];
  std::printf(
      "[ figures  ] intrinsics from 20 daemon captures: fx %.3f (%+.3f%%) fy %.3f (%+.3f%%) cx %.3f (%+.3f%%) "
      "cy %.3f (%+.3f%%), RMS %.4f px, 1-sigma %s px\n",
      fx, 100 * (fx / truth_.camera.fx() - 1), fy, 100 * (fy / truth_.camera.fy() - 1), cx,
      100 * (cx / truth_.camera.cx() - 1), cy, 100 * (cy / truth_.camera.cy() - 1), k["rms_px"].get<double>(),
      k["std_dev_px"].dump().c_str());
  EXPECT_NEAR(fx, truth_.camera.fx(), 0.005 * truth_.camera.fx());
  EXPECT_NEAR(fy, truth_.camera.fy(), 0.005 * truth_.camera.fy());
  EXPECT_NEAR(cx, truth_.camera.cx(), 0.005 * truth_.camera.cx());
  EXPECT_NEAR(cy, truth_.camera.cy(), 0.005 * truth_.camera.cy());
  EXPECT_EQ(k["views"].size(), 20u);
  EXPECT_NE(r.text.find("RMS"), std::string::npos) << "mfcd-ctl prints the figures table:\n" << r.text;
  EXPECT_EQ(bytes(camera_file()), original_) << "compute writes nothing";

  // Apply needs a confirmation; without a terminal mfcd-ctl refuses, and so does the daemon.
  r = ctl("calibrate apply");
  EXPECT_EQ(r.exit, 1) << r.text;
  EXPECT_NE(r.text.find("--yes"), std::string::npos) << r.text;
  EXPECT_FALSE(proc_->ctl({{"cmd", "calibrate"}, {"action", "apply"}})["ok"]);
  EXPECT_EQ(bytes(camera_file()), original_);

  r = ctl("calibrate apply --yes");
  ASSERT_EQ(r.exit, 0) << r.text;
  EXPECT_NE(r.answer.value("reload", "").find("reloaded"), std::string::npos) << r.text;
  // The only recipe has no template file: nothing for the new camera to invalidate.
  ASSERT_TRUE(r.answer["invalidated"].is_array()) << r.text;
  EXPECT_TRUE(r.answer["invalidated"].empty()) << r.text;
  const std::string applied = bytes(camera_file());
  EXPECT_NE(applied, original_);
  EXPECT_EQ(bytes(fs::path(camera_file()).concat(".previous")), original_);
  const auto written = mfcd::vision::load_camera_config(camera_file());
  EXPECT_DOUBLE_EQ(written.camera.fx(), fx);
  EXPECT_EQ(written.flashes.positions_mm.size(), truth_.flashes.positions_mm.size()) << "only the intrinsics change";
  EXPECT_DOUBLE_EQ(written.working_distance_mm, truth_.working_distance_mm);
  const json st = proc_->ctl({{"cmd", "status"}});
  EXPECT_EQ(st["state"], "ready") << st.dump();
  EXPECT_FALSE(st["calibration"]["active"]);
  EXPECT_TRUE(proc_->ctl({{"cmd", "trigger"}})["ok"]) << "picking resumes after apply";

  r = ctl("calibrate rollback --yes");
  ASSERT_EQ(r.exit, 0) << r.text;
  EXPECT_EQ(bytes(camera_file()), original_);
  EXPECT_EQ(bytes(fs::path(camera_file()).concat(".previous")), applied) << "a second rollback undoes the first";
}

void CalibrationE2E::run_hand_eye(calib::HandEyeMode mode) {
  const bool in_hand = mode == calib::HandEyeMode::eye_in_hand;
  auto r = ctl(std::string("calibrate hand-eye start --mode ") + (in_hand ? "eye-in-hand" : "eye-to-hand"));
  ASSERT_EQ(r.exit, 0) << r.text;
  // A hand-eye view without a pose is refused before anything is captured.
  r = ctl("calibrate capture");
  EXPECT_EQ(r.exit, 1);
  EXPECT_NE(r.text.find("--pose"), std::string::npos) << r.text;

  const auto poses = hand_eye_poses(mode, 10, in_hand ? 21 : 11);
  for (const auto& p : poses) {
    r = ctl("calibrate capture --pose " + pose_arg(p));
    ASSERT_EQ(r.exit, 0) << r.text;
  }
  r = ctl("calibrate compute");
  ASSERT_EQ(r.exit, 0) << r.text;
  const json he = r.answer["hand_eye"][in_hand ? "flange_T_camera" : "base_T_camera"];
  const double got[6] = {he["x_mm"], he["y_mm"], he["z_mm"], he["rx_deg"], he["ry_deg"], he["rz_deg"]};
  const cv::Matx44d X = matrix(got), xtrue = matrix(in_hand ? kEyeInHandCamera : kEyeToHandCamera);
  const double dt = cv::norm(calib::translation_of(X) - calib::translation_of(xtrue));
  const double dr = calib::rotation_angle_deg(calib::rotation_of(X), calib::rotation_of(xtrue));
  std::printf("[ figures  ] hand-eye %s from 10 daemon captures: %.4f mm, %.5f deg from the truth; RMS %.4f px\n",
              in_hand ? "eye-in-hand" : "eye-to-hand", dt, dr, r.answer["hand_eye"]["rms_px"].get<double>());
  EXPECT_LT(dt, 0.5);
  EXPECT_LT(dr, 0.1);

  // Check step on a pose not used for the calibration.
  const auto more = hand_eye_poses(mode, 1, 99);
  r = ctl("calibrate check --pose " + pose_arg(more[0]));
  ASSERT_EQ(r.exit, 0) << r.text;
  EXPECT_LT(r.answer["origin_error_mm"].get<double>(), 1.0) << r.text;

  r = ctl("calibrate apply --yes");
  ASSERT_EQ(r.exit, 0) << r.text;
  const auto written = mfcd::vision::load_camera_config(camera_file());
  ASSERT_TRUE(written.hand_eye.has_value());
  EXPECT_EQ(written.hand_eye->mode, mode);
  EXPECT_EQ(bytes(fs::path(camera_file()).concat(".previous")), original_);
  r = ctl("calibrate rollback --yes");
  ASSERT_EQ(r.exit, 0) << r.text;
  EXPECT_EQ(bytes(camera_file()), original_);
}

TEST_F(CalibrationE2E, HandEyeEyeToHandRecoversTheSimulatedCell) { run_hand_eye(calib::HandEyeMode::eye_to_hand); }

TEST_F(CalibrationE2E, HandEyeEyeInHandRecoversTheSimulatedCell) { run_hand_eye(calib::HandEyeMode::eye_in_hand); }

TEST_F(CalibrationE2E, DegenerateMotionAndAbortWriteNothing) {
  ASSERT_EQ(ctl("calibrate hand-eye start --mode eye-to-hand").exit, 0);
  // Every view turns the plate about the same axis (the optical axis through the plate centre):
  // the rotation about that axis leaves the hand-eye translation undetermined.
  const cv::Matx44d X = matrix(kEyeToHandCamera), Y = matrix(kEyeToHandPlate);
  const cv::Vec3d centre(40, 25, 0);
  for (int i = 0; i < 8; ++i) {
    const cv::Matx33d R = calib::euler_to_rotation(0, 0, -30 + 8.0 * i);
    const cv::Matx44d T = calib::make_transform(R, cv::Vec3d(0, 0, 300) - R * centre);
    const auto r = ctl("calibrate capture --pose " +
                       pose_arg(reported(calib::sim_flange_pose(calib::HandEyeMode::eye_to_hand, X, Y, T))));
    ASSERT_EQ(r.exit, 0) << r.text;
  }
  auto r = ctl("calibrate compute");
  EXPECT_EQ(r.exit, 1) << r.text;
  EXPECT_NE(r.text.find("degenerate"), std::string::npos) << r.text;
  EXPECT_EQ(bytes(camera_file()), original_);
  // Nothing computed: apply is refused even with --yes.
  r = ctl("calibrate apply --yes");
  EXPECT_EQ(r.exit, 1) << r.text;
  EXPECT_NE(r.text.find("nothing computed"), std::string::npos) << r.text;
  // A second session cannot start over a running one.
  EXPECT_EQ(ctl("calibrate intrinsics start").exit, 1);
  r = ctl("calibrate abort");
  ASSERT_EQ(r.exit, 0) << r.text;
  EXPECT_EQ(proc_->ctl({{"cmd", "status"}})["state"], "ready");
  EXPECT_EQ(bytes(camera_file()), original_);
  EXPECT_FALSE(fs::exists(fs::path(camera_file()).concat(".previous")));
  // Nothing to roll back to.
  r = ctl("calibrate rollback --yes");
  EXPECT_EQ(r.exit, 1) << r.text;
  EXPECT_EQ(bytes(camera_file()), original_);
}

// The flange pose read from the PLC's robot pose block (register map v2), written by a real
// libmodbus client with FC 0x10.
TEST_F(CalibrationE2E, PoseFromThePlcRegisters) {
  modbus_t* mb = modbus_new_tcp("127.0.0.1", proc_->modbus_port());
  ASSERT_EQ(modbus_connect(mb), 0);
  const auto write = [&](const calib::RobotPose& p, std::uint16_t valid, std::uint16_t seq) {
    std::uint16_t block[14];
    const double v[6] = {p.x_mm, p.y_mm, p.z_mm, p.rx_deg, p.ry_deg, p.rz_deg};
    for (int i = 0; i < 6; ++i) {
      const auto w = mfcd::motion::encode_float(static_cast<float>(v[i]), mfcd::motion::WordOrder::ABCD);
      block[2 * i] = w[0], block[2 * i + 1] = w[1];
    }
    block[12] = valid, block[13] = seq;
    return modbus_write_registers(mb, reg::kRobotPoseX, 14, block);
  };
  ASSERT_EQ(ctl("calibrate hand-eye start --mode eye-to-hand").exit, 0);
  auto r = ctl("calibrate capture --pose-from-plc");
  EXPECT_EQ(r.exit, 1);
  EXPECT_NE(r.text.find("has not written"), std::string::npos) << r.text;

  const auto poses = hand_eye_poses(calib::HandEyeMode::eye_to_hand, 2, 5);
  ASSERT_EQ(write(poses[0], 0, 1), 14);
  r = ctl("calibrate capture --pose-from-plc");
  EXPECT_EQ(r.exit, 1);
  EXPECT_NE(r.text.find("VALID"), std::string::npos) << r.text;

  ASSERT_EQ(write(poses[0], 1, 2), 14);
  r = ctl("calibrate capture --pose-from-plc");
  ASSERT_EQ(r.exit, 0) << r.text;
  EXPECT_EQ(r.answer["pose_source"], "plc");
  EXPECT_EQ(r.answer["pose_sequence"], 2);
  EXPECT_NEAR(r.answer["pose"][0].get<double>(), poses[0].x_mm, 1e-3);
  // The same sequence number again: the PLC has not moved on, the view is refused.
  r = ctl("calibrate capture --pose-from-plc");
  EXPECT_EQ(r.exit, 1);
  EXPECT_NE(r.text.find("SEQ"), std::string::npos) << r.text;
  ASSERT_EQ(write(poses[1], 1, 3), 14);
  r = ctl("calibrate capture --pose-from-plc");
  ASSERT_EQ(r.exit, 0) << r.text;
  EXPECT_EQ(r.answer["views"], 2);

  // READY is clear during the session, so the PLC's TRIGGER is refused with "busy".
  const std::uint16_t trigger[4] = {1, 7, 0, 0};
  EXPECT_EQ(modbus_write_registers(mb, reg::kCommand, 4, trigger), -1);
  EXPECT_EQ(errno, EMBXSBUSY);
  // A malformed pose block (valid flag 2) is refused with exception 0x03 and changes nothing.
  EXPECT_EQ(write(poses[1], 2, 4), -1);
  EXPECT_EQ(errno, EMBXILVAL);
  modbus_close(mb);
  modbus_free(mb);
  ASSERT_EQ(ctl("calibrate abort").exit, 0);
}

}  // namespace

// The camera file's disk is full when the operator applies a hand-eye calibration: apply fails
// with the reason, the camera file and the directory are as they were (no temporary file left),
// the session stays open, and once space is freed the same apply succeeds.
class CalibrationFullDisk : public CalibrationE2E {
 protected:
  void SetUp() override {
    proc_ = std::make_unique<DaemonProcess>("calib-full");
    small_ = proc_->dir() / "small";
    // 64 kB: the camera file (~3 kB) and a filler that takes every other block.
    disk_ = std::make_unique<SmallDisk>(small_, "64k");
    if (!disk_->mounted()) GTEST_SKIP() << SmallDisk::kSkipReason;
    start(small_);
  }
  void TearDown() override {
    if (!disk_ || !disk_->mounted()) return;
    // The daemon stops before its camera file's disk goes, and that goes before the test
    // directory is removed (a mount point cannot be).
    proc_->signal(SIGTERM);
    proc_->wait(15000);
    disk_.reset();
  }
  // Writes zeros into `filler` until the disk refuses: no block is left.
  void fill() const {
    std::ofstream out(small_ / "filler", std::ios::binary);
    const std::string block(4096, '\0');
    while (out.write(block.data(), static_cast<std::streamsize>(block.size())) && out.flush()) {
    }
  }
  std::vector<std::string> entries() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(small_)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }
  fs::path small_;
  std::unique_ptr<SmallDisk> disk_;
};

TEST_F(CalibrationFullDisk, ApplyFailsWithTheReasonChangesNothingAndSucceedsOnceThereIsSpace) {
  auto r = ctl("calibrate hand-eye start --mode eye-to-hand");
  ASSERT_EQ(r.exit, 0) << r.text;
  for (const auto& p : hand_eye_poses(calib::HandEyeMode::eye_to_hand, 10, 11)) {
    r = ctl("calibrate capture --pose " + pose_arg(p));
    ASSERT_EQ(r.exit, 0) << r.text;
  }
  r = ctl("calibrate compute");
  ASSERT_EQ(r.exit, 0) << r.text;

  fill();
  const std::vector<std::string> before = entries();
  r = ctl("calibrate apply --yes");
  EXPECT_EQ(r.exit, 1) << r.text;
  EXPECT_NE(r.text.find("No space left on device"), std::string::npos) << r.text;
  EXPECT_NE(r.text.find("nothing changed"), std::string::npos) << r.text;
  EXPECT_EQ(bytes(camera_file()), original_);
  EXPECT_EQ(entries(), before) << "no temporary or .previous file is left behind";
  const json st = proc_->ctl({{"cmd", "status"}});
  EXPECT_EQ(st["state"], "calibrating") << "the computed result is kept for another apply: " << st.dump();

  fs::remove(small_ / "filler");
  r = ctl("calibrate apply --yes");
  ASSERT_EQ(r.exit, 0) << r.text;
  EXPECT_NE(bytes(camera_file()), original_);
  EXPECT_EQ(bytes(fs::path(camera_file()).concat(".previous")), original_);
  ASSERT_TRUE(mfcd::vision::load_camera_config(camera_file()).hand_eye.has_value());
  EXPECT_EQ(proc_->ctl({{"cmd", "status"}})["state"], "ready");
}
