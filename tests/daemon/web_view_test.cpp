// The web view's side of the daemon: the lock-free hand-over of the last cycle's images
// (LatestFrame) and the frame path's promise that a browser polling the web view costs it no
// allocation (the cell's threads, with WebView and WebServer serving images meanwhile).
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <thread>

#include "../hal/alloc_counter.hpp"
#include "daemon/cell.hpp"
#include "daemon/latest_frame.hpp"
#include "daemon/web_server.hpp"
#include "daemon/web_view.hpp"
#include "run_cycle.hpp"
#include "test_vision_stage.hpp"

using namespace mfcd::daemon;
using namespace std::chrono_literals;

namespace {

// The HTTP status of GET `path` from 127.0.0.1:port and the body's size; 0 when no answer.
int http_get(std::uint16_t port, const std::string& path, std::size_t* body_bytes = nullptr) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(port);
  inet_pton(AF_INET, "127.0.0.1", &a.sin_addr);
  int status = 0;
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0) {
    const std::string req = "GET " + path + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n";
    ::send(fd, req.data(), req.size(), MSG_NOSIGNAL);
    std::string answer;
    char buf[65536];
    for (;;) {
      pollfd p{fd, POLLIN, 0};
      if (::poll(&p, 1, 3000) <= 0) break;
      const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
      if (n <= 0) break;
      answer.append(buf, static_cast<std::size_t>(n));
    }
    if (answer.rfind("HTTP/1.1 ", 0) == 0) status = std::atoi(answer.c_str() + 9);
    const auto body = answer.find("\r\n\r\n");
    if (body_bytes) *body_bytes = body == std::string::npos ? 0 : answer.size() - body - 4;
  }
  ::close(fd);
  return status;
}

}  // namespace

// A reader never sees a frame half written: every pixel of a frame it takes belongs to the cycle
// its result names, and cycles only go forward.
TEST(LatestFrame, TheReaderAlwaysTakesAWholeFrameAndNeverAnOlderOne) {
  const mfcd::hal::ImageFormat format{64, 48, 8};
  FrameSlot slot;
  slot.allocate(format);
  LatestFrame frames;
  frames.allocate(cv::Size(64, 48));
  EXPECT_EQ(frames.newest(), nullptr) << "nothing published yet";
  constexpr int kFrames = 3000;
  std::atomic<bool> done{false};
  std::thread writer([&] {
    CycleResult r;
    cv::Mat1b edges(48, 64);
    for (int i = 1; i <= kFrames; ++i) {
      const int v = i % 200;
      for (int k = 0; k < 8; ++k) slot.mfc.flash[static_cast<std::size_t>(k)] = v + k;
      slot.mfc.ambient = v;
      edges = 255 - v;
      r.request.cycle_id = static_cast<std::uint64_t>(i);
      frames.publish(slot, r, &edges);
    }
    done = true;
  });
  std::uint64_t last = 0, taken = 0;
  while (!done.load() || last < kFrames) {
    const WebFrame* f = frames.newest();
    if (!f) continue;
    const auto cycle = f->result.request.cycle_id;
    ASSERT_GE(cycle, last) << "an older frame after a newer one";
    const int v = static_cast<int>(cycle % 200);
    ASSERT_EQ(cv::countNonZero(f->ambient != v), 0) << "ambient of another cycle in frame " << cycle;
    ASSERT_EQ(cv::countNonZero(f->composite != v + 7), 0) << "composite is the max of the flashes";
    ASSERT_TRUE(f->have_edges);
    ASSERT_EQ(cv::countNonZero(f->edges != 255 - v), 0);
    taken += cycle != last;
    last = cycle;
  }
  writer.join();
  EXPECT_EQ(last, static_cast<std::uint64_t>(kFrames)) << "the last frame reaches the reader";
  std::printf("[ figures  ] %llu distinct frames taken of %d published\n", static_cast<unsigned long long>(taken),
              kFrames);
}

// The web view serves the cell's images while cycles run; the cell's threads allocate nothing
// (the web server's threads, named mfcd-web*, may).
TEST(WebView, FramePathDoesNotAllocateWhileABrowserPolls) {
  DaemonConfig config = parse_config(
      "camera:\n  model: camera-sim.yaml\nrecipes:\n  - {id: 0, part: any, obj_id: 0}\n"
      "daemon:\n  realtime_priority: 0\n  cycle_budget_ms: 1000\n"
      "web:\n  enabled: true\n  port: 0\n",
      "test", {MFC_SOURCE_DIR "/config", MFC_SOURCE_DIR});
  ASSERT_FALSE(config.web_root.empty());
  Cell cell(config, [](const DaemonConfig&) { return std::make_unique<test::TruthVisionStage>(20ms, true, 0, true); });
  cell.start();
  WebView view(fs::temp_directory_path() / "mfcd-no-snapshots");
  WebServer server(config.web, view, config.web_root);
  server.start();
  view.set_cell(cell.web_frames(), cell.parts(), mfcd::vision::load_camera_config(config.camera.model));

  CycleRequest r;
  r.origin = CycleOrigin::Benchmark;
  const auto run_cycle = [&](std::uint64_t id) {
    r.cycle_id = id;
    r.trigger = Clock::now();
    r.deadline = r.trigger + 900ms;
    return test::run_cycle(cell, r);
  };
  for (std::uint64_t i = 1; i <= 3; ++i) ASSERT_EQ(run_cycle(i).error, CycleError::None);
  ASSERT_EQ(http_get(server.port(), "/api/image/overlay.png"), 200) << "an overlay once a cycle has run";

  std::atomic<bool> stop{false};
  std::atomic<int> served{0};
  std::thread browser([&] {
    pthread_setname_np(pthread_self(), "mfcd-web-test");  // its own allocations are not the frame path's
    while (!stop.load()) {
      for (const char* path : {"/api/image/overlay.png", "/api/image/ambient.png", "/api/image/edges.png"}) {
        std::size_t bytes = 0;
        if (http_get(server.port(), path, &bytes) == 200 && bytes > 100) ++served;
      }
    }
  });
  mfcd::hal::test::exclude_threads_named("mfcd-web");
  const std::uint64_t before = mfcd::hal::test::allocation_count_outside_excluded();
  const int served_before = served.load();
  for (std::uint64_t i = 4; i < 24; ++i) EXPECT_EQ(run_cycle(i).error, CycleError::None);
  const std::uint64_t allocations = mfcd::hal::test::allocation_count_outside_excluded() - before;
  const int images = served.load() - served_before;
  mfcd::hal::test::exclude_threads_named(nullptr);
  stop = true;
  browser.join();
  server.stop();
  view.set_cell(nullptr, {}, {});
  EXPECT_EQ(allocations, 0u) << "acquisition, vision worker and results while the web view served " << images
                             << " images";
  EXPECT_GE(images, 5) << "the browser's requests ran alongside the cycles";
  std::printf("[ figures  ] %d images served during 20 cycles\n", images);
}
