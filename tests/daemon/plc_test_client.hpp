#pragma once
// A PLC as the daemon tests drive it: a real libmodbus client reading the status block and
// writing TRIGGER / RESET, polling the way a PLC program does.
#include <modbus/modbus.h>

#include <Eigen/Geometry>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <thread>
#include <vector>

#include "motion/float_codec.hpp"
#include "motion/register_map.hpp"

namespace mfcd::daemon::test {

using namespace std::chrono_literals;

struct Regs {
  std::uint16_t r[28]{};
  std::uint16_t at(int addr) const { return r[addr - motion::reg::kStatus]; }
  float f(int addr) const { return motion::decode_float(at(addr), at(addr + 1), motion::WordOrder::ABCD); }
};

struct Client {
  explicit Client(int port) {
    ctx = modbus_new_tcp("127.0.0.1", port);
    connected = ctx && modbus_connect(ctx) == 0;
    modbus_set_response_timeout(ctx, 3, 0);
  }
  ~Client() {
    modbus_close(ctx);
    modbus_free(ctx);
  }
  bool read(Regs& out) { return modbus_read_registers(ctx, motion::reg::kStatus, 28, out.r) == 28; }
  int trigger(std::uint16_t job, std::uint16_t recipe, std::uint16_t mode = 0) {
    const std::uint16_t cmd[4] = {1, job, recipe, mode};
    return modbus_write_registers(ctx, motion::reg::kCommand, 4, cmd) == 4 ? 0 : errno;
  }
  bool wait_for(std::uint16_t job, Regs& out, int timeout_ms = 20000) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
    while (std::chrono::steady_clock::now() < end) {
      if (read(out) && out.at(motion::reg::kJobIdEcho) == job) return true;
      std::this_thread::sleep_for(5ms);
    }
    return false;
  }
  bool wait_ready(int timeout_ms = 20000) {
    Regs r;
    const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
    while (std::chrono::steady_clock::now() < end) {
      if (read(r) && (r.at(motion::reg::kStatus) & motion::reg::kReady)) return true;
      std::this_thread::sleep_for(5ms);
    }
    return false;
  }
  modbus_t* ctx = nullptr;
  bool connected = false;
};

// x, y, z mm and rx, ry, rz degrees with R = Rz * Ry * Rx (docs/register-map.md "Orientation").
inline Eigen::Isometry3d pose_of(double x, double y, double z, double rx, double ry, double rz) {
  const double d = M_PI / 180;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() =
      (Eigen::AngleAxisd(rz * d, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(ry * d, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(rx * d, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

// The robot pose block (36..49) in one FC 0x10, ABCD; returns what modbus_write_registers does.
inline int write_robot_pose(modbus_t* mb, const double (&v)[6], std::uint16_t valid, std::uint16_t seq) {
  std::uint16_t block[14];
  for (int i = 0; i < 6; ++i) {
    const auto w = motion::encode_float(static_cast<float>(v[i]), motion::WordOrder::ABCD);
    block[2 * i] = w[0], block[2 * i + 1] = w[1];
  }
  block[12] = valid, block[13] = seq;
  return modbus_write_registers(mb, motion::reg::kRobotPoseX, 14, block);
}

// The whole register map in one FC 0x03 read; empty when the read fails.
inline std::vector<std::uint16_t> read_map(modbus_t* mb) {
  std::vector<std::uint16_t> m(motion::reg::kBlockSize);
  if (modbus_read_registers(mb, 0, motion::reg::kBlockSize, m.data()) != motion::reg::kBlockSize) m.clear();
  return m;
}
// The float32 pair at register `a` of a map read, ABCD.
inline float float_at(const std::vector<std::uint16_t>& m, int a) {
  return motion::decode_float(m[static_cast<std::size_t>(a)], m[static_cast<std::size_t>(a) + 1],
                              motion::WordOrder::ABCD);
}

// Waits for READY, starts a job (COMMAND, JOB_ID, RECIPE_ID, MODE 0 in one write) and waits for
// its result: the map read that shows it, or empty after ~60 s.
inline std::vector<std::uint16_t> run_job(modbus_t* mb, std::uint16_t command, std::uint16_t job,
                                          std::uint16_t recipe = 0) {
  for (int i = 0; i < 4000; ++i) {
    const auto m = read_map(mb);
    if (!m.empty() && (m[motion::reg::kStatus] & motion::reg::kReady)) break;
    std::this_thread::sleep_for(5ms);
  }
  const std::uint16_t cmd[4] = {command, job, recipe, 0};
  if (modbus_write_registers(mb, motion::reg::kCommand, 4, cmd) != 4) return {};
  for (int i = 0; i < 12000; ++i) {
    auto m = read_map(mb);
    if (!m.empty() && m[motion::reg::kJobIdEcho] == job && !(m[motion::reg::kStatus] & motion::reg::kBusy)) return m;
    std::this_thread::sleep_for(5ms);
  }
  return {};
}

}  // namespace mfcd::daemon::test
