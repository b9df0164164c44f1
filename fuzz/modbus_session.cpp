// A Modbus/TCP session through the real server, motion/modbus_server.cpp: the input is sent over
// a loopback TCP connection in chunks whose sizes the input itself chooses (so frames split and
// merge at every boundary), the answers are drained, the connection closed. The server runs on
// its own thread for the whole run, as in mfcd. Besides the sanitizers, the harness checks that
// the server thread keeps serving and that, every 64 inputs, a well-formed request on a fresh
// connection still gets the right answer.

#include "fuzz/fuzz_support.hpp"
#include "motion/modbus_server.hpp"
#include "motion/register_map.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>

#include <chrono>
#include <cstdio>
#include <memory>

namespace {

using namespace mfcd::motion;
using mfcd::UniqueFd;

UniqueFd connect_to(std::uint16_t port) {
  UniqueFd fd(::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0));
  sockaddr_in dst{};
  dst.sin_family = AF_INET;
  dst.sin_port = htons(port);
  inet_pton(AF_INET, "127.0.0.1", &dst.sin_addr);
  if (::connect(fd.get(), reinterpret_cast<sockaddr*>(&dst), sizeof dst) != 0) mfcd::fuzz::finding("cannot connect");
  const int one = 1;
  ::setsockopt(fd.get(), IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  return fd;
}

// Reads what arrives within `ms` (answers, or the server's close).
void drain(int fd, int ms) {
  std::uint8_t buf[4096];
  pollfd p{fd, POLLIN, 0};
  while (::poll(&p, 1, ms) > 0 && ::recv(fd, buf, sizeof buf, MSG_DONTWAIT) > 0) ms = 1;
}

void check_still_answers(const ModbusServer& server) {
  UniqueFd fd = connect_to(server.port());
  // Read MAP_VERSION (register 24, one register): transaction 0x4D46, unit 1.
  const std::uint8_t request[12] = {0x4D, 0x46, 0, 0, 0, 6, 1, 0x03, 0, reg::kMapVersionReg, 0, 1};
  ::send(fd.get(), request, sizeof request, MSG_NOSIGNAL);
  std::uint8_t answer[11] = {};
  std::size_t have = 0;
  pollfd p{fd.get(), POLLIN, 0};
  while (have < sizeof(answer) && ::poll(&p, 1, 2000) > 0) {
    const ssize_t n = ::recv(fd.get(), answer + have, sizeof answer - have, 0);
    if (n <= 0) break;
    have += static_cast<std::size_t>(n);
  }
  if (have != sizeof answer || answer[0] != 0x4D || answer[7] != 0x03 || answer[8] != 2 ||
      answer[10] != reg::kMapVersion) {
    std::fprintf(stderr, "fuzz harness: %zu answer bytes; server: %u clients, %llu refused, %llu dropped\n", have,
                 server.stats().clients_now, static_cast<unsigned long long>(server.stats().connections_refused),
                 static_cast<unsigned long long>(server.stats().connections_dropped));
    mfcd::fuzz::finding("the server no longer answers a well-formed read");
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static ModbusServer* server = [] {
    ModbusServerConfig config;
    config.bind_address = "127.0.0.1";
    config.port = 0;
    config.frame_timeout = std::chrono::milliseconds(50);  // a cut-off frame frees its slot quickly
    auto* s = new ModbusServer(config);
    s->start();
    RobotReport report;
    report.ready = 1;
    report.vision_ok = 1;
    s->publish(report);
    return s;
  }();
  static unsigned inputs = 0;
  if (size == 0) return 0;
  {
    UniqueFd fd = connect_to(server->port());
    // Byte 0: the chunk sizes' pattern; the rest goes out in chunks of 1 + (pattern >> k) % 13.
    const std::uint8_t pattern = data[0];
    std::size_t pos = 1, k = 0;
    while (pos < size) {
      const std::size_t shift = k % 8;
      ++k;
      const std::size_t chunk = std::min<std::size_t>(size - pos, 1 + ((pattern >> shift) * 7u + k) % 13);
      if (::send(fd.get(), data + pos, chunk, MSG_NOSIGNAL) < 0) break;  // the server closed: done
      pos += chunk;
    }
    drain(fd.get(), 1);
  }
  if (!server->serving()) mfcd::fuzz::finding("the server thread ended");
  if (++inputs % 64 == 0) check_still_answers(*server);
  return 0;
}
