// Helpers for talking to a ModbusServer over real loopback sockets in tests.
#pragma once

#include "motion/float_codec.hpp"
#include "motion/modbus_server.hpp"
#include "motion/register_map.hpp"

#include <arpa/inet.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace mfcd::motion::test {

// A server on 127.0.0.1 at a port the kernel picks (ModbusServer::port() tells which).
inline ModbusServerConfig loopback_config(WordOrder order = WordOrder::ABCD) {
  ModbusServerConfig c;
  c.bind_address = "127.0.0.1";
  c.port = 0;
  c.word_order = order;
  return c;
}

// Polls `done` every 10 ms for up to 3 s; its last answer.
template <typename F>
bool eventually(F done) {
  for (int i = 0; i < 300 && !done(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  return done();
}

// A plain TCP socket for sending hand-made (often malformed) frames.
class RawClient {
 public:
  explicit RawClient(std::uint16_t port, const char* source = nullptr) {
    fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (source) {
      sockaddr_in src{};
      src.sin_family = AF_INET;
      inet_pton(AF_INET, source, &src.sin_addr);
      if (::bind(fd_, reinterpret_cast<sockaddr*>(&src), sizeof(src)) < 0) throw std::runtime_error("bind source");
    }
    sockaddr_in dst{};
    dst.sin_family = AF_INET;
    dst.sin_port = htons(port);
    inet_pton(AF_INET, "127.0.0.1", &dst.sin_addr);
    if (::connect(fd_, reinterpret_cast<sockaddr*>(&dst), sizeof(dst)) < 0) throw std::runtime_error("connect");
  }
  ~RawClient() { close(); }
  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  void send(const std::vector<std::uint8_t>& bytes) { ::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL); }
  // Bytes received within timeout_ms (up to `want`), or nullopt when the server closed
  // the connection without sending anything.
  std::optional<std::vector<std::uint8_t>> receive(std::size_t want, int timeout_ms = 2000) {
    std::vector<std::uint8_t> out;
    while (out.size() < want) {
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, timeout_ms) <= 0) break;
      std::uint8_t buf[512];
      const ssize_t n = ::recv(fd_, buf, std::min(sizeof(buf), want - out.size()), 0);
      if (n <= 0) {
        if (out.empty()) return std::nullopt;
        break;
      }
      out.insert(out.end(), buf, buf + n);
    }
    return out;
  }
  // True when the server closes the connection within timeout_ms.
  bool closed_by_server(int timeout_ms = 2000) {
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, timeout_ms) <= 0) return false;
    std::uint8_t b;
    return ::recv(fd_, &b, 1, 0) <= 0;
  }

 private:
  int fd_ = -1;
};

// A Modbus/TCP ADU with a consistent MBAP length.
inline std::vector<std::uint8_t> make_adu(std::uint16_t transaction, std::vector<std::uint8_t> pdu,
                                          std::uint8_t unit = 0xff) {
  const std::size_t length = pdu.size() + 1;
  std::vector<std::uint8_t> out{
      static_cast<std::uint8_t>(transaction >> 8), static_cast<std::uint8_t>(transaction & 0xff), 0,   0,
      static_cast<std::uint8_t>(length >> 8),      static_cast<std::uint8_t>(length & 0xff),      unit};
  for (std::uint8_t b : pdu)  // (not insert(): GCC 12 -O3 warns falsely on it)
    out.push_back(b);
  return out;
}

// A real libmodbus client, as a PLC-side library would use it.
struct LibmodbusClient {
  explicit LibmodbusClient(std::uint16_t port) {
    ctx = modbus_new_tcp("127.0.0.1", port);
    if (!ctx || modbus_connect(ctx) != 0) throw std::runtime_error("libmodbus connect failed");
    modbus_set_response_timeout(ctx, 2, 0);
  }
  ~LibmodbusClient() { modbus_free(ctx); }
  std::vector<std::uint16_t> read(int address, int count) {
    std::vector<std::uint16_t> regs(count);
    if (modbus_read_registers(ctx, address, count, regs.data()) != count)
      throw std::runtime_error(std::string("read failed: ") + modbus_strerror(errno));
    return regs;
  }
  // Returns 0 or the errno libmodbus reports (EMBXILVAL, EMBXSBUSY, ...).
  int write(int address, std::vector<std::uint16_t> values) {
    if (modbus_write_registers(ctx, address, static_cast<int>(values.size()), values.data()) ==
        static_cast<int>(values.size()))
      return 0;
    return errno;
  }
  modbus_t* ctx;
};

inline float reg_float(const std::vector<std::uint16_t>& block, int at, WordOrder order) {
  return decode_float(block[at], block[at + 1], order);
}

// Polls the job id echo the way a PLC does, until it equals job.
inline std::vector<std::uint16_t> wait_for_echo(LibmodbusClient& plc, std::uint16_t job) {
  for (int i = 0; i < 300; ++i) {
    auto block = plc.read(0, reg::kBlockSize);
    if (block[reg::kJobIdEcho] == job) return block;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  throw std::runtime_error("job id echo never arrived");
}

}  // namespace mfcd::motion::test
