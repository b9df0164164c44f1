// CanPublisher against the kernel: link-down reporting everywhere, and real frames on vcan0
// where the machine has it (the VM tier); elsewhere those tests skip.
#include "motion/can_publisher.hpp"
#include "motion/register_map.hpp"

#include <gtest/gtest.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <map>
#include <thread>

using namespace mfcd::motion;
using namespace std::chrono_literals;

namespace {

template <typename Pred>
bool eventually(Pred pred, std::chrono::milliseconds limit = 3000ms) {
  const auto end = std::chrono::steady_clock::now() + limit;
  while (std::chrono::steady_clock::now() < end) {
    if (pred()) return true;
    std::this_thread::sleep_for(10ms);
  }
  return pred();
}

// A raw CAN reader on an interface, the in-process stand-in for candump.
class CanReader {
 public:
  explicit CanReader(const char* iface) {
    fd_ = ::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
    sockaddr_can addr{};
    addr.can_family = AF_CAN;
    addr.can_ifindex = static_cast<int>(if_nametoindex(iface));
    if (fd_ < 0 || ::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) < 0)
      throw std::runtime_error("cannot open CAN reader");
  }
  ~CanReader() { ::close(fd_); }
  std::optional<can_frame> next(int timeout_ms = 3000) {
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, timeout_ms) <= 0) return std::nullopt;
    can_frame f;
    if (::read(fd_, &f, sizeof(f)) != sizeof(f)) return std::nullopt;
    return f;
  }

 private:
  int fd_ = -1;
};

bool have_vcan0() {
  if (if_nametoindex("vcan0") == 0) return false;
  const int fd = ::socket(PF_CAN, SOCK_RAW, CAN_RAW);
  if (fd < 0) return false;
  ::close(fd);
  return true;
}

}  // namespace

TEST(CanPublisher, MissingInterfaceIsReportedAndRetried) {
  CanConfig config;
  config.interface = "mfcnope0";
  config.retry_interval = 50ms;
  CanPublisher publisher(config);
  publisher.start();
  RobotReport r;
  r.ready = 1;
  publisher.publish(r);  // must not block or fail with the link down
  EXPECT_TRUE(eventually([&] { return publisher.stats().link_attempts >= 3; }));
  EXPECT_EQ(publisher.state(), CanLinkState::Down);
  const std::string error = publisher.last_error();
  EXPECT_NE(error.find("can interface 'mfcnope0'"), std::string::npos) << error;
  EXPECT_NE(error.find("No such device"), std::string::npos) << error;
  EXPECT_EQ(publisher.stats().frames_sent, 0u);
  publisher.stop();
}

TEST(CanPublisher, BadConfigurationIsNamed) {
  CanConfig config;
  config.interface = "a-name-longer-than-ifnamsiz";
  EXPECT_NE(config.validate().find("can interface 'a-name-longer-than-ifnamsiz'"), std::string::npos);
  EXPECT_THROW(CanPublisher{config}, std::invalid_argument);
  config = {};
  config.id_base = 0x7f0;
  EXPECT_NE(config.validate().find("id_base"), std::string::npos);
}

TEST(CanPublisher, SendsStatusHeartbeatVersionAndPickOnVcan0) {
  if (!have_vcan0())
    GTEST_SKIP() << "vcan0 not present (needs the vcan module: modprobe vcan; ip link add vcan0 type vcan; "
                    "ip link set vcan0 up) - runs in the VM tier";
  CanReader reader("vcan0");
  CanConfig config;
  config.interface = "vcan0";
  config.heartbeat_period = 100ms;
  config.software_version = 0x0203;  // release 2.3.17
  config.software_patch = 17;
  CanPublisher publisher(config);
  publisher.start();
  ASSERT_TRUE(eventually([&] { return publisher.state() == CanLinkState::Up; }));

  RobotReport r;
  r.ready = 1;
  r.vision_ok = 1;
  r.job_id = 33;
  r.pick_valid = 1;
  r.pick = {412.25f, -87.5f, 130.0f, 179.5f, -2.25f, 45.0f};
  r.score = 0.9125f;
  publisher.publish(r);

  std::map<canid_t, can_frame> last;
  std::optional<CanPick> pick;
  int heartbeats = 0, versions = 0, versions_after_heartbeat = 0;
  canid_t previous = 0;
  const auto end = std::chrono::steady_clock::now() + 3s;
  while (std::chrono::steady_clock::now() < end && (!pick || heartbeats < 3 || versions < 3)) {
    const auto f = reader.next();
    if (!f) break;
    last[f->can_id] = *f;
    if (f->can_id == kCanDefaultBase + kCanHeartbeatOffset) ++heartbeats;
    if (f->can_id == kCanDefaultBase + kCanVersionOffset) {
      ++versions;
      if (previous == kCanDefaultBase + kCanHeartbeatOffset) ++versions_after_heartbeat;
    }
    previous = f->can_id;
    if (f->can_id == kCanDefaultBase + kCanPickCOffset && last.count(kCanDefaultBase + kCanPickAOffset) &&
        last.count(kCanDefaultBase + kCanPickBOffset))
      pick = decode_pick({last[kCanDefaultBase + kCanPickAOffset], last[kCanDefaultBase + kCanPickBOffset], *f},
                         kCanDefaultBase);
  }
  ASSERT_TRUE(pick) << "no complete pick seen on vcan0";
  EXPECT_EQ(pick->job_id, 33);
  EXPECT_NEAR(pick->pose.x_mm, 412.25f, 0.006f);
  EXPECT_NEAR(pick->pose.rz_deg, 45.0f, 0.006f);
  EXPECT_GE(heartbeats, 3);
  // One version frame each heartbeat period, right after the heartbeat frame.
  EXPECT_GE(versions, 3);
  EXPECT_EQ(versions_after_heartbeat, versions);
  EXPECT_LE(std::abs(heartbeats - versions), 1);
  ASSERT_TRUE(last.count(kCanDefaultBase + kCanVersionOffset));
  const auto version = decode_version(last[kCanDefaultBase + kCanVersionOffset], kCanDefaultBase);
  ASSERT_TRUE(version);
  EXPECT_EQ(version->major, 2);
  EXPECT_EQ(version->minor, 3);
  EXPECT_EQ(version->patch, 17);
  EXPECT_EQ(version->map_version, reg::kMapVersion);
  EXPECT_EQ(version->dbc_version, kCanDbcVersion);
  ASSERT_TRUE(last.count(kCanDefaultBase + kCanStatusOffset));
  EXPECT_EQ(last[kCanDefaultBase + kCanStatusOffset].data[2], 33);
  EXPECT_EQ(publisher.stats().picks_sent, 1u);
}

TEST(CanPublisher, VersionFollowsTheHeartbeatLeaseOnVcan0) {
  if (!have_vcan0()) GTEST_SKIP() << "vcan0 not present - runs in the VM tier";
  CanReader reader("vcan0");
  CanConfig config;
  config.interface = "vcan0";
  config.heartbeat_period = 50ms;
  CanPublisher publisher(config);
  publisher.lease_health(std::chrono::steady_clock::now() - 1s);  // lapsed: mfcd counts as hung
  publisher.start();
  ASSERT_TRUE(eventually([&] { return publisher.state() == CanLinkState::Up; }));
  std::map<canid_t, int> seen;
  const auto end = std::chrono::steady_clock::now() + 400ms;
  while (std::chrono::steady_clock::now() < end) {
    const auto f = reader.next(100);
    if (f) ++seen[f->can_id];
  }
  EXPECT_GE(seen[kCanDefaultBase + kCanStatusOffset], 3) << "status goes out every period, lease or not";
  EXPECT_EQ(seen[kCanDefaultBase + kCanHeartbeatOffset], 0);
  EXPECT_EQ(seen[kCanDefaultBase + kCanVersionOffset], 0) << "the version frame is withheld with the heartbeat";
}

TEST(CanPublisher, LinkDownAndBackOnVcan0) {
  if (!have_vcan0()) GTEST_SKIP() << "vcan0 not present - runs in the VM tier";
  if (::geteuid() != 0 || std::system("command -v ip >/dev/null") != 0)
    GTEST_SKIP() << "needs root and iproute2 to take vcan0 down";
  CanConfig config;
  config.interface = "vcan0";
  config.heartbeat_period = 50ms;
  config.retry_interval = 50ms;
  CanPublisher publisher(config);
  publisher.start();
  ASSERT_TRUE(eventually([&] { return publisher.state() == CanLinkState::Up; }));
  ASSERT_EQ(std::system("ip link set vcan0 down"), 0);
  EXPECT_TRUE(eventually([&] { return publisher.state() == CanLinkState::Down; }));
  EXPECT_NE(publisher.last_error().find("vcan0"), std::string::npos);
  ASSERT_EQ(std::system("ip link set vcan0 up"), 0);
  EXPECT_TRUE(eventually([&] { return publisher.state() == CanLinkState::Up; }));
  const auto sent = publisher.stats().frames_sent;
  EXPECT_TRUE(eventually([&] { return publisher.stats().frames_sent > sent + 2; }));
}
