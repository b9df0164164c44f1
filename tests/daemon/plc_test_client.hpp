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
  bool waitFor(std::uint16_t job, Regs& out, int timeoutMs = 20000) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeoutMs);
    while (std::chrono::steady_clock::now() < end) {
      if (read(out) && out.at(motion::reg::kJobIdEcho) == job) return true;
      std::this_thread::sleep_for(5ms);
    }
    return false;
  }
  bool waitReady(int timeoutMs = 20000) {
    Regs r;
    const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeoutMs);
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
inline Eigen::Isometry3d poseOf(double x, double y, double z, double rx, double ry, double rz) {
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
inline int writeRobotPose(modbus_t* mb, const double (&v)[6], std::uint16_t valid, std::uint16_t seq) {
  std::uint16_t block[14];
  for (int i = 0; i < 6; ++i) {
    const auto w = motion::encode_float(static_cast<float>(v[i]), motion::WordOrder::ABCD);
    block[2 * i] = w[0], block[2 * i + 1] = w[1];
  }
  block[12] = valid, block[13] = seq;
  return modbus_write_registers(mb, motion::reg::kRobotPoseX, 14, block);
}

}  // namespace mfcd::daemon::test
