#pragma once
// The web operator view: a small HTTP server (cpp-httplib) that serves web/'s page and JSON views of
// the daemon (status, last cycle, statistics, snapshots) to a browser. Read-only: every method but
// GET and HEAD is answered 405. It runs on its own threads at the lowest CPU priority (SCHED_IDLE,
// else nice 19) and only ever calls WebData from those threads, so the page polling the daemon
// costs the cycle nothing but the provider's copies.
//
// Bounded against whatever arrives on the socket (nothing a peer sends can stop the daemon, hold
// its memory or stall WebServer::stop()):
//   - kWorkers threads answer requests; at most kQueued accepted connections wait for one, beyond
//     that the listener stops accepting and the kernel's backlog (kBacklog) holds the rest, so the
//     server holds at most kWorkers + kQueued + 1 connections' descriptors (and its listener's);
//   - one request per connection (no keep-alive), so no worker waits on a browser's idle kept-alive
//     socket; a new connection that sends nothing holds one for kIoTimeout;
//   - from when a worker takes a connection up, its request must arrive within kRequestDeadline,
//     in at most kMaxRequestBytes (line, headers and body together); no wait for the peer lasts
//     longer than kIoTimeout; the whole connection, response included, at most kConnectionDeadline;
//   - stop() shuts every open connection down, so it returns within a few milliseconds.
// cpp-httplib 0.11 (Debian 12) bounds none of these itself (it accepts any number of header lines,
// each kept in memory); WebServer reads the socket through its own stream to do so. Plain HTTP:
// the view carries nothing secret and the cell's network is closed (no TLS, no authentication
// beyond allow_list).
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "daemon/web_settings.hpp"

namespace mfcd::daemon {

// What the page shows, supplied by the daemon. Called only from the web server's threads (at most
// kWorkers at once), never from the cycle's, so an implementation must be thread-safe. It should hand
// out copies of what the daemon has published rather than take a lock the frame path also takes:
// the caller runs at SCHED_IDLE and can be preempted for a long time while holding such a lock.
class WebData {
 public:
  virtual ~WebData() = default;
  // The control socket's "status" object: state, ready, vision_ok, error_code, recipe, camera,
  // modbus {clients, ...}, version, commit, recipes [...], calibration {...}.
  virtual nlohmann::json status() = 0;
  // The last cycle's result (report.hpp's result_json: cycle, job_id, times_ms {total, ...}, error,
  // candidates [...], chosen, ranked [...], pick {...}); null before the first cycle.
  virtual nlohmann::json last_cycle() = 0;
  // CycleStats::to_json(): cycles, overruns, errors, pick_results {...}, percentiles_ms {total {p50, ...}}.
  virtual nlohmann::json stats() = 0;
  // {"directory": "...", "snapshots": [{"name": "<dir name>", "files": ["overlay.png", ...], ...}]}
  virtual nlohmann::json snapshots() = 0;
  // The last cycle's image `name` ("ambient", "edges" or "overlay") encoded as PNG into `png`;
  // false when there is none.
  virtual bool image_png(const std::string& name, std::string& png) = 0;
  // The file `file` of snapshot `snapshot` (each one path component, already checked: no '/', no
  // "..", only [A-Za-z0-9._-]): its path inside the snapshot directory, or empty when there is no
  // such file.
  virtual std::filesystem::path snapshot_file(const std::string& snapshot, const std::string& file) = 0;
};

class WebServer {
 public:
  static constexpr int kWorkers = 4;  // a browser opens several connections, some idle (preconnects)
  static constexpr std::size_t kQueued = 16;
  static constexpr int kBacklog = 32;  // connections the kernel completes before they are accepted
  static constexpr std::chrono::milliseconds kIoTimeout{2000};
  static constexpr std::chrono::milliseconds kRequestDeadline{5000};
  static constexpr std::chrono::milliseconds kConnectionDeadline{60000};
  static constexpr std::size_t kMaxRequestBytes = 32 * 1024;
  // cpp-httplib's payload limit (413). It reads no body of a GET and the methods that carry one
  // are refused before theirs is read, so this is a second line behind kMaxRequestBytes.
  static constexpr std::size_t kMaxBodyBytes = 4 * 1024;

  // Serves web_root's index.html, app.js and style.css (read on each request) and data's views.
  // settings.enabled is the caller's business: a constructed server serves once start()ed.
  WebServer(WebSettings settings, WebData& data, std::filesystem::path web_root);
  ~WebServer();  // stop()
  WebServer(const WebServer&) = delete;
  WebServer& operator=(const WebServer&) = delete;

  // Binds bind_address:port and starts serving on a thread of its own. Throws std::system_error
  // (std::runtime_error when the address is not numeric) naming the address and port when it
  // cannot bind, std::invalid_argument for a bad allow-list entry, std::logic_error when started twice.
  void start();
  // Stops accepting, ends the open connections and joins every thread. Idempotent; start() may
  // follow.
  void stop();
  bool running() const { return thread_.joinable(); }
  // The bound port (the kernel's choice when settings.port is 0); 0 before start().
  std::uint16_t port() const { return bound_port_; }

 private:
  class Http;  // the cpp-httplib server (web_server.cpp), so <httplib.h> stays out of the daemon

  WebSettings settings_;
  WebData& data_;
  std::filesystem::path web_root_;
  std::unique_ptr<Http> http_;
  std::thread thread_;
  std::atomic<bool> listen_returned_{false};
  std::uint16_t bound_port_ = 0;
};

}  // namespace mfcd::daemon
