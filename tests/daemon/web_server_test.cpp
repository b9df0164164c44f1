// WebServer (daemon/web_server.hpp) on a kernel-chosen loopback port with a fake WebData: the JSON
// views, images, static files and snapshot downloads; what it refuses (path traversal, methods
// other than GET/HEAD, peers outside the allow-list); and what arrives on the socket that must not
// stop it (random bytes, half requests, oversized and endless headers, idle connections), each
// followed by a GET that must still be answered. cpp-httplib's client for well-formed requests,
// raw sockets for the rest.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <map>
#include <mutex>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <system_error>
#include <thread>
#include <utility>
#include <vector>

#include <httplib.h>

#include "base/unique_fd.hpp"
#include "daemon/web_server.hpp"

using namespace mfcd::daemon;
using namespace std::chrono_literals;
using mfcd::UniqueFd;
using nlohmann::json;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

// What a daemon would publish, set by each test; records the snapshot files asked for.
class FakeData : public WebData {
 public:
  json status() override {
    std::lock_guard lock(mutex);
    if (throw_in_status) throw std::runtime_error("provider failed");
    return status_json;
  }
  json last_cycle() override {
    std::lock_guard lock(mutex);
    return last_json;
  }
  json stats() override {
    std::lock_guard lock(mutex);
    return stats_json;
  }
  json snapshots() override {
    std::lock_guard lock(mutex);
    return snapshots_json;
  }
  bool image_png(const std::string& name, std::string& png) override {
    std::lock_guard lock(mutex);
    const auto it = images.find(name);
    if (it == images.end()) return false;
    png = it->second;
    return true;
  }
  fs::path snapshot_file(const std::string& snapshot, const std::string& file) override {
    std::lock_guard lock(mutex);
    asked.emplace_back(snapshot, file);
    const fs::path p = snapshot_root / snapshot / file;
    return fs::is_regular_file(p) ? p : fs::path();
  }

  std::mutex mutex;
  json status_json = {{"state", "ready"}, {"ready", true}, {"vision_ok", true}, {"error_code", 0}, {"recipe", 1}};
  json last_json = nullptr;
  json stats_json = {{"cycles", 3}, {"percentiles_ms", {{"total", {{"p50", 101.5}}}}}};
  json snapshots_json = {{"snapshots", json::array()}};
  std::map<std::string, std::string> images;
  fs::path snapshot_root;
  std::vector<std::pair<std::string, std::string>> asked;
  bool throw_in_status = false;
};

// One raw TCP connection to the server.
class Raw {
 public:
  explicit Raw(std::uint16_t port) : fd_(::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0)) {
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(port);
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    connected_ = ::connect(fd_.get(), reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  }
  bool connected() const { return connected_; }
  // False once the server has ended the connection (EPIPE, ECONNRESET) or `wait` passed unsent.
  bool send(const std::string& bytes, std::chrono::milliseconds wait = 2000ms) {
    std::size_t off = 0;
    const auto until = Clock::now() + wait;
    while (off < bytes.size()) {
      pollfd p{fd_.get(), POLLOUT, 0};
      if (::poll(&p, 1, 50) <= 0) {
        if (Clock::now() > until) return false;
        continue;
      }
      const ssize_t n = ::send(fd_.get(), bytes.data() + off, bytes.size() - off, MSG_NOSIGNAL | MSG_DONTWAIT);
      if (n < 0 && errno != EAGAIN && errno != EINTR) return false;
      if (n > 0) off += static_cast<std::size_t>(n);
    }
    return true;
  }
  void end_sending() { ::shutdown(fd_.get(), SHUT_WR); }
  // What arrives until the server closes (or `wait` passes; then closed() is false).
  std::string receive(std::chrono::milliseconds wait = 5000ms) {
    std::string out;
    const auto until = Clock::now() + wait;
    closed_ = false;
    while (Clock::now() < until) {
      pollfd p{fd_.get(), POLLIN, 0};
      if (::poll(&p, 1, 20) <= 0) continue;
      char buf[4096];
      const ssize_t n = ::recv(fd_.get(), buf, sizeof buf, 0);
      if (n <= 0) {
        closed_ = true;
        break;
      }
      out.append(buf, static_cast<std::size_t>(n));
    }
    return out;
  }
  bool closed() const { return closed_; }

 private:
  UniqueFd fd_;
  bool connected_ = false;
  bool closed_ = false;
};

std::string status_line(const std::string& response) { return response.substr(0, response.find("\r\n")); }

class WebServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("mfcd-web-test-" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "web");
    fs::create_directories(dir_ / "snapshots" / "20250101T000000Z-cycle7");
    write(dir_ / "web" / "index.html", "<!doctype html><title>t</title><p id=\"status-state\"></p>");
    write(dir_ / "web" / "app.js", "'use strict';");
    write(dir_ / "web" / "style.css", "body{}");
    write(dir_ / "web" / "secret.txt", "not served");
    write(dir_ / "outside.txt", "outside the web root");
    write(dir_ / "snapshots" / "20250101T000000Z-cycle7" / "result.json", "{\"cycle\": 7}");
    data_.snapshot_root = dir_ / "snapshots";
    settings_.port = 0;
  }
  void TearDown() override {
    server_.reset();
    fs::remove_all(dir_);
  }

  static void write(const fs::path& p, const std::string& text) { std::ofstream(p, std::ios::binary) << text; }

  void start() {
    server_ = std::make_unique<WebServer>(settings_, data_, dir_ / "web");
    server_->start();
    ASSERT_NE(server_->port(), 0);
  }
  httplib::Client client() const {
    httplib::Client c("127.0.0.1", server_->port());
    c.set_connection_timeout(2);
    c.set_read_timeout(10);
    return c;
  }
  httplib::Result get(const std::string& path) const { return client().Get(path.c_str()); }
  // The server still answers a plain GET.
  void expect_alive() const {
    const auto r = get("/api/status");
    ASSERT_TRUE(r) << "no answer: " << httplib::to_string(r.error());
    EXPECT_EQ(r->status, 200);
    EXPECT_EQ(json::parse(r->body)["state"], "ready");
  }
  std::string raw(const std::string& bytes) const {
    Raw c(server_->port());
    EXPECT_TRUE(c.connected());
    c.send(bytes);
    c.end_sending();
    return c.receive();
  }

  fs::path dir_;
  FakeData data_;
  WebSettings settings_;
  std::unique_ptr<WebServer> server_;
};

TEST(WebSettings, Validate) {
  WebSettings s;
  EXPECT_EQ(s.validate(), "");
  s.port = 0;
  EXPECT_EQ(s.validate(), "") << "0: the kernel chooses, as for modbus.port";
  s = {};
  s.bind_address = "localhost";
  EXPECT_NE(s.validate().find("web bind_address 'localhost'"), std::string::npos) << s.validate();
  s = {};
  s.bind_address = "::";
  s.allow_list = {"192.168.10.0/24", "fd00::/8"};
  EXPECT_EQ(s.validate(), "");
  s.allow_list = {"10.0.0.0/33"};
  EXPECT_EQ(s.validate().rfind("web allow_list entry '10.0.0.0/33'", 0), 0u) << s.validate();
}

TEST_F(WebServerTest, JsonViews) {
  data_.last_json = {{"cycle", 12}, {"job_id", 3}, {"times_ms", {{"total", 98.5}}}, {"candidates", json::array()}};
  data_.snapshots_json = {{"snapshots", {{{"name", "20250101T000000Z-cycle7"}, {"files", {"result.json"}}}}}};
  start();
  for (const auto& [path, expected] :
       std::vector<std::pair<std::string, json>>{{"/api/status", data_.status_json},
                                                 {"/api/last", data_.last_json},
                                                 {"/api/stats", data_.stats_json},
                                                 {"/api/snapshots", data_.snapshots_json}}) {
    const auto r = get(path);
    ASSERT_TRUE(r) << path;
    EXPECT_EQ(r->status, 200) << path;
    EXPECT_EQ(r->get_header_value("Content-Type"), "application/json") << path;
    EXPECT_EQ(r->get_header_value("Cache-Control"), "no-store") << path;
    EXPECT_EQ(json::parse(r->body), expected) << path;
  }
  // Before the first cycle the last cycle is null.
  data_.last_json = nullptr;
  const auto r = get("/api/last");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->body, "null");
}

TEST_F(WebServerTest, ProviderFailureIs500AndInvalidUtf8IsReplaced) {
  start();
  data_.throw_in_status = true;
  auto r = get("/api/status");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 500);
  EXPECT_EQ(json::parse(r->body)["error"], "provider failed");
  data_.throw_in_status = false;
  data_.status_json = {{"state", "ready"}, {"camera", std::string("cam\xff\xfe")}};
  r = get("/api/status");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_EQ(json::parse(r->body)["camera"], "cam\xEF\xBF\xBD\xEF\xBF\xBD");
}

TEST_F(WebServerTest, StaticFilesOnlyThePage) {
  start();
  auto r = get("/");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_EQ(r->get_header_value("Content-Type"), "text/html; charset=utf-8");
  EXPECT_NE(r->body.find("status-state"), std::string::npos);
  EXPECT_NE(r->get_header_value("Content-Security-Policy").find("default-src 'self'"), std::string::npos);
  r = get("/app.js");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_EQ(r->get_header_value("Content-Type"), "text/javascript; charset=utf-8");
  r = get("/style.css");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_EQ(r->body, "body{}");
  // Nothing else of the web root, and nothing outside it.
  for (const char* path : {"/secret.txt", "/../outside.txt", "/%2e%2e/outside.txt", "/web/index.html", "/index.htm"}) {
    const std::string response = raw(std::string("GET ") + path + " HTTP/1.1\r\nHost: x\r\n\r\n");
    EXPECT_EQ(status_line(response), "HTTP/1.1 404 Not Found") << path;
    EXPECT_EQ(response.find("not served"), std::string::npos) << path;
    EXPECT_EQ(response.find("outside the web root"), std::string::npos) << path;
  }
}

TEST_F(WebServerTest, ImagesAre404UntilThereIsOne) {
  start();
  for (const char* name : {"ambient", "edges", "overlay"}) {
    const auto r = get(std::string("/api/image/") + name + ".png?cycle=4");
    ASSERT_TRUE(r) << name;
    EXPECT_EQ(r->status, 404) << name;
    EXPECT_EQ(r->get_header_value("Content-Type"), "application/json") << name;
    EXPECT_EQ(json::parse(r->body)["error"], std::string("no ") + name + " image yet");
  }
  const std::string png("\x89PNG\r\n\x1a\n-fake-", 14);
  data_.images["overlay"] = png;
  auto r = get("/api/image/overlay.png?cycle=5");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_EQ(r->get_header_value("Content-Type"), "image/png");
  EXPECT_EQ(r->body, png);
  r = get("/api/image/camera.png");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 404);
}

TEST_F(WebServerTest, SnapshotDownload) {
  start();
  auto r = get("/snapshots/20250101T000000Z-cycle7/result.json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_EQ(r->body, "{\"cycle\": 7}");
  EXPECT_EQ(r->get_header_value("Content-Disposition"), "attachment; filename=\"result.json\"");
  EXPECT_EQ(r->get_header_value("Content-Type"), "application/json");
  // One byte range is served; several are refused (cpp-httplib 0.11 would copy the body per range).
  httplib::Headers range = {{"Range", "bytes=1-6"}};
  r = client().Get("/snapshots/20250101T000000Z-cycle7/result.json", range);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 206);
  EXPECT_EQ(r->body, "\"cycle");
  range = {{"Range", "bytes=0-,0-,0-"}};
  r = client().Get("/snapshots/20250101T000000Z-cycle7/result.json", range);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 416);
  // No such file: the provider's empty path is a 404.
  r = get("/snapshots/20250101T000000Z-cycle7/missing.png");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 404);
}

TEST_F(WebServerTest, SnapshotPathTraversalRefused) {
  start();
  const std::vector<std::string> paths = {
      "/snapshots/../outside.txt",
      "/snapshots/../../etc/passwd",
      "/snapshots/20250101T000000Z-cycle7/..",
      "/snapshots/../20250101T000000Z-cycle7/result.json",
      "/snapshots/%2e%2e/outside.txt",
      "/snapshots/..%2f..%2fetc/passwd",
      "/snapshots/20250101T000000Z-cycle7%2f..%2f../outside.txt",
      "/snapshots/20250101T000000Z-cycle7/..%2f..%2foutside.txt",
      "/snapshots/.hidden/result.json",
      "/snapshots/a%00b/result.json",
      "/snapshots/a%0d%0aX-Injected:%201/result.json",
      "/snapshots/20250101T000000Z-cycle7/result.json/extra",
  };
  for (const std::string& path : paths) {
    const std::string response = raw("GET " + path + " HTTP/1.1\r\nHost: x\r\n\r\n");
    const std::string status = status_line(response);
    EXPECT_TRUE(status == "HTTP/1.1 400 Bad Request" || status == "HTTP/1.1 404 Not Found") << path << ": " << status;
    EXPECT_EQ(response.find("outside the web root"), std::string::npos) << path;
    EXPECT_EQ(response.find("X-Injected"), std::string::npos) << path;
  }
  // None of them reached the provider: only well-formed names are passed on.
  std::lock_guard lock(data_.mutex);
  EXPECT_TRUE(data_.asked.empty()) << data_.asked.front().first << "/" << data_.asked.front().second;
}

TEST_F(WebServerTest, OnlyGetAndHead) {
  settings_.allow_control = true;  // no control endpoints yet: changes nothing
  start();
  auto c = client();
  std::vector<std::pair<std::string, httplib::Result>> results;
  results.emplace_back("POST", c.Post("/api/status", "{}", "application/json"));
  results.emplace_back("PUT", c.Put("/api/status", "{}", "application/json"));
  results.emplace_back("PATCH", c.Patch("/api/status", "{}", "application/json"));
  results.emplace_back("DELETE", c.Delete("/api/status"));
  results.emplace_back("OPTIONS", c.Options("/api/status"));
  results.emplace_back("POST /", c.Post("/", std::string(100000, 'x'), "text/plain"));  // a body it never reads
  for (const auto& [what, r] : results) {
    ASSERT_TRUE(r) << what << ": " << httplib::to_string(r.error());
    EXPECT_EQ(r->status, 405) << what;
    EXPECT_EQ(r->get_header_value("Allow"), "GET, HEAD") << what;
  }
  const auto head = c.Head("/api/status");
  ASSERT_TRUE(head);
  EXPECT_EQ(head->status, 200);
  EXPECT_TRUE(head->body.empty());
  // Methods cpp-httplib does not know are a bad request before any route.
  EXPECT_EQ(status_line(raw("BREW /api/status HTTP/1.1\r\nHost: x\r\n\r\n")), "HTTP/1.1 400 Bad Request");
  expect_alive();
}

TEST_F(WebServerTest, AllowListRefusesOtherPeers) {
  settings_.bind_address = "127.0.0.1";
  settings_.allow_list = {"10.0.0.0/8"};
  start();
  for (const char* path : {"/api/status", "/", "/api/image/overlay.png", "/snapshots/a/b"}) {
    const auto r = get(path);
    ASSERT_TRUE(r) << path;
    EXPECT_EQ(r->status, 403) << path;
    EXPECT_NE(json::parse(r->body)["error"].get<std::string>().find("127.0.0.1"), std::string::npos);
  }
  const auto r = client().Post("/api/status", "{}", "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 403);
  server_.reset();
  settings_.allow_list = {"10.0.0.0/8", "127.0.0.0/8"};
  start();
  expect_alive();
}

TEST_F(WebServerTest, StartFailsNamingAddressAndPort) {
  UniqueFd taken(::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0));
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::bind(taken.get(), reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
  ASSERT_EQ(::listen(taken.get(), 1), 0);
  socklen_t len = sizeof a;
  ASSERT_EQ(::getsockname(taken.get(), reinterpret_cast<sockaddr*>(&a), &len), 0);
  settings_.port = ntohs(a.sin_port);
  WebServer s(settings_, data_, dir_ / "web");
  try {
    s.start();
    FAIL() << "bound a port in use";
  } catch (const std::system_error& e) {
    EXPECT_EQ(e.code(), std::errc::address_in_use);
    EXPECT_NE(std::string(e.what()).find("127.0.0.1:" + std::to_string(settings_.port)), std::string::npos) << e.what();
  }
  EXPECT_FALSE(s.running());

  settings_.port = 0;
  settings_.allow_list = {"not-an-address"};
  WebServer bad_list(settings_, data_, dir_ / "web");
  EXPECT_THROW(bad_list.start(), std::invalid_argument);
}

TEST_F(WebServerTest, StopAndStartAgain) {
  start();
  expect_alive();
  EXPECT_THROW(server_->start(), std::logic_error);
  server_->stop();
  EXPECT_FALSE(server_->running());
  EXPECT_EQ(server_->port(), 0);
  server_->stop();  // idempotent
  server_->start();
  expect_alive();
}

TEST_F(WebServerTest, RandomBytesDoNotStopIt) {
  start();
  std::mt19937 rng(42);
  for (int round = 0; round < 20; ++round) {
    std::string bytes(static_cast<std::size_t>(1 + rng() % 8192), '\0');
    for (char& c : bytes) c = static_cast<char>(rng());
    if (round % 2) bytes.insert(0, "GET /api/status HTTP/1.1\r\n");  // a good start, then noise
    Raw c(server_->port());
    ASSERT_TRUE(c.connected());
    c.send(bytes);
    c.end_sending();
    const std::string response = c.receive();
    EXPECT_TRUE(c.closed()) << "round " << round;
    if (!response.empty()) {
      EXPECT_EQ(response.rfind("HTTP/1.1 4", 0), 0u) << status_line(response);
    }
  }
  expect_alive();
}

TEST_F(WebServerTest, HalfRequestsTimeOutWhileOthersAreServed) {
  start();
  std::vector<std::unique_ptr<Raw>> held;
  for (const char* part : {"GET /api/sta", "GET /api/status HTTP/1.1\r\nHost: x\r\n", "G"}) {
    held.push_back(std::make_unique<Raw>(server_->port()));
    ASSERT_TRUE(held.back()->connected());
    held.back()->send(part);
  }
  expect_alive();  // a fourth worker answers meanwhile
  for (auto& c : held) {
    const auto t0 = Clock::now();
    c->receive(WebServer::kRequestDeadline + 2s);
    EXPECT_TRUE(c->closed());
    EXPECT_LT(Clock::now() - t0, WebServer::kRequestDeadline + 1s);
  }
  expect_alive();
}

TEST_F(WebServerTest, OversizedRequestsAreCut) {
  start();
  // A 100 KB header line; a 20 KB request target (414).
  std::string response = raw("GET /api/status HTTP/1.1\r\nX-Big: " + std::string(100000, 'a') + "\r\n\r\n");
  EXPECT_TRUE(response.empty() || response.rfind("HTTP/1.1 400", 0) == 0) << status_line(response);
  response = raw("GET /" + std::string(20000, 'a') + " HTTP/1.1\r\nHost: x\r\n\r\n");
  EXPECT_EQ(status_line(response), "HTTP/1.1 414 URI Too Long");
  // A body on a GET is never read (cpp-httplib reads bodies of POST, PUT, PATCH only, and those
  // are refused first); the connection ends after the answer.
  response = raw("GET /api/status HTTP/1.1\r\nContent-Length: 1000000\r\n\r\n" + std::string(1000000, 'b'));
  EXPECT_EQ(status_line(response), "HTTP/1.1 200 OK");
  expect_alive();
}

TEST_F(WebServerTest, EndlessHeadersAreCutOff) {
  // cpp-httplib 0.11 keeps every header line it is sent; WebServer stops reading a request at
  // kMaxRequestBytes, so the server ends a connection that never stops sending headers.
  start();
  Raw c(server_->port());
  ASSERT_TRUE(c.connected());
  ASSERT_TRUE(c.send("GET /api/status HTTP/1.1\r\n"));
  const std::string lines = [] {
    std::string s;
    for (int i = 0; i < 1000; ++i) s += "X-Flood-" + std::to_string(i) + ": 0123456789\r\n";
    return s;
  }();
  std::size_t sent = 0;
  const auto until = Clock::now() + 5s;
  bool ended = false;
  while (Clock::now() < until) {
    if (!c.send(lines, 500ms)) {
      ended = true;
      break;
    }
    sent += lines.size();
  }
  EXPECT_TRUE(ended) << "the server kept reading headers: " << sent << " bytes";
  expect_alive();
}

TEST_F(WebServerTest, IdleConnectionsDoNotStopIt) {
  // Connections that never send (a browser's preconnects, or worse): each holds a worker for
  // kIoTimeout at most, so a GET behind them is answered within a few of those.
  start();
  std::vector<std::unique_ptr<Raw>> idle;
  for (int i = 0; i < 3 * WebServer::kWorkers; ++i) idle.push_back(std::make_unique<Raw>(server_->port()));
  const auto t0 = Clock::now();
  const auto r = client().Get("/api/status");
  ASSERT_TRUE(r) << httplib::to_string(r.error());
  EXPECT_EQ(r->status, 200);
  EXPECT_LT(Clock::now() - t0, 4 * WebServer::kIoTimeout);
  for (auto& c : idle) {
    c->receive(4 * WebServer::kIoTimeout);
    EXPECT_TRUE(c->closed());
  }
  expect_alive();
}

TEST_F(WebServerTest, StopIsPromptWithConnectionsOpen) {
  start();
  std::vector<std::unique_ptr<Raw>> held;
  // More than the workers and the queue take: the rest wait in the kernel's backlog.
  for (std::size_t i = 0; i < WebServer::kWorkers + WebServer::kQueued + 8; ++i) {
    held.push_back(std::make_unique<Raw>(server_->port()));
    held.back()->send("GET /api/status HTTP/1.1\r\n");  // and never the rest
  }
  std::this_thread::sleep_for(100ms);  // workers are waiting on them
  const auto t0 = Clock::now();
  server_->stop();
  EXPECT_LT(Clock::now() - t0, 1s);
  for (auto& c : held) {
    c->receive(2s);
    EXPECT_TRUE(c->closed());
  }
}

// The real page (web/): the ids the daemon's tests and the browser test look for, and nothing it
// would fetch from outside the cell.
TEST(WebPage, StableIdsAndNoExternalResources) {
  const fs::path root = fs::path(MFC_SOURCE_DIR) / "web";
  const auto read = [&](const char* name) {
    std::ifstream in(root / name);
    std::stringstream s;
    s << in.rdbuf();
    EXPECT_TRUE(in.good() || in.eof()) << name;
    return s.str();
  };
  const std::string html = read("index.html"), js = read("app.js"), css = read("style.css");
  for (const char* id : {"status-state",
                         "status-ready",
                         "status-vision-ok",
                         "status-error-code",
                         "status-recipe",
                         "status-camera",
                         "status-modbus-clients",
                         "status-version",
                         "status-commit",
                         "last-cycle",
                         "last-cycle-id",
                         "last-job-id",
                         "last-total-ms",
                         "last-error",
                         "pick",
                         "candidates",
                         "ambient",
                         "edges",
                         "overlay",
                         "stats",
                         "stats-percentiles",
                         "cycle-plot",
                         "recipes-table",
                         "snapshot-list",
                         "calibration-state"})
    EXPECT_NE(html.find(std::string("id=\"") + id + "\""), std::string::npos) << id;
  for (const std::string* text : {&html, &js, &css}) {
    EXPECT_EQ(text->find("http://"), std::string::npos);
    EXPECT_EQ(text->find("https://"), std::string::npos);
    EXPECT_EQ(text->find("//cdn"), std::string::npos);
  }
}

}  // namespace
