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
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <memory>

namespace {

using namespace mfcd::motion;
using mfcd::UniqueFd;

// libFuzzer's timeout alarm (SIGALRM every -timeout/2 + 1 s, installed without SA_RESTART)
// interrupts whatever blocking call the harness is in: every call below that can wait goes on
// after EINTR, so an alarm is never taken for the server's fault.

// poll() for one descriptor until `ms` have passed, going on after an interrupting alarm with the
// time left: 1 when ready, 0 when the time ran out, -1 on another error.
int poll_for(int fd, short events, int ms) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(ms);
  for (;;) {
    pollfd p{fd, events, 0};
    const auto left = std::chrono::ceil<std::chrono::milliseconds>(end - std::chrono::steady_clock::now());
    const int ready = ::poll(&p, 1, static_cast<int>(std::max<std::chrono::milliseconds::rep>(left.count(), 0)));
    if (ready >= 0 || errno != EINTR) return ready;
  }
}

// A connected socket; connect() runs non-blocking and is waited for with poll(), which an alarm
// may interrupt without losing the connection under way.
UniqueFd connect_to(std::uint16_t port) {
  UniqueFd fd(::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0));
  sockaddr_in dst{};
  dst.sin_family = AF_INET;
  dst.sin_port = htons(port);
  inet_pton(AF_INET, "127.0.0.1", &dst.sin_addr);
  int error = 0;
  if (::connect(fd.get(), reinterpret_cast<sockaddr*>(&dst), sizeof dst) != 0) {
    error = errno;
    if (error == EINPROGRESS || error == EINTR) {
      const int ready = poll_for(fd.get(), POLLOUT, 5000);
      socklen_t len = sizeof error;
      if (ready != 1 || ::getsockopt(fd.get(), SOL_SOCKET, SO_ERROR, &error, &len) != 0) error = ETIMEDOUT;
    }
  }
  if (error != 0) {
    std::fprintf(stderr, "fuzz harness: connect to 127.0.0.1:%u: %s\n", port, std::strerror(error));
    mfcd::fuzz::finding("cannot connect");
  }
  const int flags = ::fcntl(fd.get(), F_GETFL);
  ::fcntl(fd.get(), F_SETFL, flags & ~O_NONBLOCK);
  const int one = 1;
  ::setsockopt(fd.get(), IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  return fd;
}

// Sends all of `bytes`; false when the server closed the connection.
bool send_all(int fd, const std::uint8_t* bytes, std::size_t size) {
  for (std::size_t sent = 0; sent < size;) {
    const ssize_t n = ::send(fd, bytes + sent, size - sent, MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    sent += static_cast<std::size_t>(n);
  }
  return true;
}

// Reads what arrives within `ms` (answers, or the server's close).
void drain(int fd, int ms) {
  std::uint8_t buf[4096];
  while (poll_for(fd, POLLIN, ms) > 0 && ::recv(fd, buf, sizeof buf, MSG_DONTWAIT) > 0) ms = 1;
}

void check_still_answers(const ModbusServer& server) {
  UniqueFd fd = connect_to(server.port());
  // Read MAP_VERSION (register 24, one register): transaction 0x4D46, unit 1.
  const std::uint8_t request[12] = {0x4D, 0x46, 0, 0, 0, 6, 1, 0x03, 0, reg::kMapVersionReg, 0, 1};
  send_all(fd.get(), request, sizeof request);
  std::uint8_t answer[11] = {};
  std::size_t have = 0;
  while (have < sizeof(answer)) {
    if (poll_for(fd.get(), POLLIN, 2000) <= 0) break;
    const ssize_t n = ::recv(fd.get(), answer + have, sizeof answer - have, MSG_DONTWAIT);
    if (n < 0 && (errno == EINTR || errno == EAGAIN)) continue;
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
      if (!send_all(fd.get(), data + pos, chunk)) break;  // the server closed: done
      pos += chunk;
    }
    drain(fd.get(), 1);
  }
  if (!server->serving()) mfcd::fuzz::finding("the server thread ended");
  if (++inputs % 64 == 0) check_still_answers(*server);
  return 0;
}
