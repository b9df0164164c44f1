#include "daemon/web_server.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <condition_variable>
#include <deque>
#include <fstream>
#include <functional>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <system_error>
#include <utility>

// Debian's libcpp-httplib-dev is the compiled form of cpp-httplib: the header declares, the shared
// library defines, and both must agree on CPPHTTPLIB_OPENSSL/ZLIB/BROTLI_SUPPORT (they change the
// classes' layout), so the defines come from its pkg-config file (daemon/CMakeLists.txt), not here.
#include <httplib.h>

#include "base/unique_fd.hpp"
#include "motion/ip_allow_list.hpp"

namespace mfcd::daemon {

namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

namespace {

// The calling thread's CPU share drops to the least the scheduler gives: SCHED_IDLE (runs only
// when nothing else of normal priority wants the core), else nice 19. Lowering is always allowed.
void lower_priority_of_this_thread() noexcept {
#ifdef SCHED_IDLE
  sched_param param{};
  param.sched_priority = 0;
  if (pthread_setschedparam(pthread_self(), SCHED_IDLE, &param) == 0) return;
#endif
  // Linux applies PRIO_PROCESS with a thread id to that thread alone.
  ::setpriority(PRIO_PROCESS, static_cast<id_t>(::gettid()), 19);
}

bool wait_for(int fd, short events, Clock::time_point until) noexcept {
  for (;;) {
    const auto left = std::chrono::ceil<std::chrono::milliseconds>(until - Clock::now()).count();
    pollfd p{fd, events, 0};
    const int n = ::poll(&p, 1, static_cast<int>(std::max<long long>(0, left)));
    if (n > 0) return true;  // POLLHUP and POLLERR too: the read or write that follows says what happened
    if (n == 0 || errno != EINTR) return false;
  }
}

// One connection's bytes as cpp-httplib reads and writes them, with the limits its own socket
// stream lacks: a byte budget and a deadline for the request, a deadline for the whole connection,
// and no wait on the peer longer than kIoTimeout.
class BoundedStream final : public httplib::Stream {
 public:
  BoundedStream(int fd, Clock::time_point started) noexcept
      : fd_(fd),
        request_deadline_(started + WebServer::kRequestDeadline),
        connection_deadline_(started + WebServer::kConnectionDeadline) {}

  bool is_readable() const override { return off_ < len_ || wait_for(fd_, POLLIN, read_until()); }
  bool is_writable() const override { return wait_for(fd_, POLLOUT, write_until()); }

  ssize_t read(char* ptr, size_t size) override {
    if (off_ == len_) {
      const std::size_t budget = WebServer::kMaxRequestBytes - consumed_;
      if (budget == 0) return -1;  // the request is larger than anything this server answers
      ssize_t n;
      do {
        if (!wait_for(fd_, POLLIN, read_until())) return -1;
        n = ::recv(fd_, buf_.data(), std::min(buf_.size(), budget), MSG_DONTWAIT);
      } while (n < 0 && (errno == EINTR || errno == EAGAIN));
      if (n <= 0) return n;
      off_ = 0;
      len_ = static_cast<std::size_t>(n);
      consumed_ += len_;
    }
    const std::size_t k = std::min(size, len_ - off_);
    std::copy_n(buf_.data() + off_, k, ptr);
    off_ += k;
    return static_cast<ssize_t>(k);
  }

  ssize_t write(const char* ptr, size_t size) override {
    for (;;) {
      if (!wait_for(fd_, POLLOUT, write_until())) return -1;
      const ssize_t n = ::send(fd_, ptr, size, MSG_NOSIGNAL | MSG_DONTWAIT);
      if (n >= 0 || (errno != EINTR && errno != EAGAIN)) return n;
    }
  }

  void get_remote_ip_and_port(std::string& ip, int& port) const override { address_of(::getpeername, ip, port); }
  void get_local_ip_and_port(std::string& ip, int& port) const override { address_of(::getsockname, ip, port); }
  socket_t socket() const override { return fd_; }

 private:
  Clock::time_point read_until() const { return std::min(Clock::now() + WebServer::kIoTimeout, request_deadline_); }
  Clock::time_point write_until() const { return std::min(Clock::now() + WebServer::kIoTimeout, connection_deadline_); }
  // Numeric address and port ("" and -1 when the socket has none, which the allow-list refuses).
  void address_of(int (*get)(int, sockaddr*, socklen_t*), std::string& ip, int& port) const {
    sockaddr_storage ss{};
    socklen_t len = sizeof ss;
    std::array<char, NI_MAXHOST> host{};
    std::array<char, NI_MAXSERV> serv{};
    ip.clear();
    port = -1;
    if (get(fd_, reinterpret_cast<sockaddr*>(&ss), &len) != 0) return;
    if (::getnameinfo(reinterpret_cast<sockaddr*>(&ss), len, host.data(), host.size(), serv.data(), serv.size(),
                      NI_NUMERICHOST | NI_NUMERICSERV) != 0)
      return;
    ip = host.data();
    port = std::atoi(serv.data());
  }

  int fd_;
  Clock::time_point request_deadline_, connection_deadline_;
  std::array<char, 4096> buf_{};
  std::size_t off_ = 0, len_ = 0, consumed_ = 0;
};

// cpp-httplib's task queue: `threads` workers at the lowest priority, and at most `max_queued`
// connections waiting for one. enqueue() (the listen loop) waits while the queue is full, so the
// server stops accepting instead of holding descriptors for connections it cannot serve yet.
class BoundedPool final : public httplib::TaskQueue {
 public:
  BoundedPool(int threads, std::size_t max_queued) : max_queued_(max_queued) {
    try {
      for (int i = 0; i < threads; ++i) threads_.emplace_back([this, i] { work(i); });
    } catch (...) {  // no thread: those made so far are joined, not left to std::terminate
      shutdown();
      throw;
    }
  }
  ~BoundedPool() override { shutdown(); }

  void enqueue(std::function<void()> fn) override {
    std::unique_lock lock(mutex_);
    room_.wait(lock, [this] { return jobs_.size() < max_queued_ || shutdown_; });
    jobs_.push_back(std::move(fn));
    work_.notify_one();
  }

  // Every job queued so far still runs (it owns an accepted socket, which it closes).
  void shutdown() override {
    {
      std::lock_guard lock(mutex_);
      shutdown_ = true;
    }
    work_.notify_all();
    room_.notify_all();
    for (std::thread& t : threads_)
      if (t.joinable()) t.join();
  }

 private:
  void work(int index) {
    const std::string name = "mfcd-web-" + std::to_string(index);
    pthread_setname_np(pthread_self(), name.c_str());
    lower_priority_of_this_thread();
    for (;;) {
      std::function<void()> fn;
      {
        std::unique_lock lock(mutex_);
        work_.wait(lock, [this] { return !jobs_.empty() || shutdown_; });
        if (jobs_.empty()) return;  // shut down and drained
        fn = std::move(jobs_.front());
        jobs_.pop_front();
      }
      room_.notify_one();
      fn();
    }
  }

  const std::size_t max_queued_;
  std::mutex mutex_;
  std::condition_variable work_, room_;
  std::deque<std::function<void()>> jobs_;
  bool shutdown_ = false;
  std::vector<std::thread> threads_;
};

// A snapshot or file name the server passes on: one path component of [A-Za-z0-9._-], not starting
// with '.' (so neither "." nor ".." nor a hidden file), and short.
bool safe_component(const std::string& s) {
  if (s.empty() || s.size() > 128 || s.front() == '.') return false;
  return std::all_of(s.begin(), s.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '_' ||
           c == '-';
  });
}

std::string mime_of(const std::string& file) {
  const auto ends = [&](const char* ext) {
    const std::string e(ext);
    return file.size() >= e.size() && file.compare(file.size() - e.size(), e.size(), e) == 0;
  };
  if (ends(".html")) return "text/html; charset=utf-8";
  if (ends(".js")) return "text/javascript; charset=utf-8";
  if (ends(".css")) return "text/css; charset=utf-8";
  if (ends(".png")) return "image/png";
  if (ends(".json")) return "application/json";
  if (ends(".yaml") || ends(".yml") || ends(".txt") || ends(".csv") || ends(".log")) return "text/plain; charset=utf-8";
  return "application/octet-stream";
}

// JSON bodies never throw on the daemon's strings: invalid UTF-8 is replaced, not an exception.
void send_json(httplib::Response& res, const json& j) {
  res.set_content(j.dump(-1, ' ', false, json::error_handler_t::replace), "application/json");
}

// The reason of the statuses cpp-httplib answers by itself (its own table is not in the header).
std::string status_text(int status) {
  switch (status) {
    case 400:
      return "bad request";
    case 404:
      return "not found";
    case 413:
      return "request body too large";
    case 414:
      return "request target too long";
    case 416:
      return "range not satisfiable";
    case 500:
      return "internal error";
    default:
      return "error " + std::to_string(status);
  }
}

void send_error(httplib::Response& res, int status, const std::string& message) {
  res.status = status;
  send_json(res, {{"error", message}, {"status", status}});
}

}  // namespace

// cpp-httplib's server with the connection handling WebServer needs. process_and_close_socket is
// cpp-httplib's (private, virtual) hook for how one accepted socket is served, the one its own
// SSLServer overrides; this override serves it through BoundedStream, one request per connection,
// and keeps the open sockets so stop() can end them. process_request (protected) is cpp-httplib
// 0.11's signature; a newer cpp-httplib fails to compile here rather than serve unbounded.
class WebServer::Http final : public httplib::Server {
 public:
  explicit Http(motion::IpAllowList allow) : allow_(std::move(allow)) {}

  // `address` is the numeric peer address BoundedStream reported; fails closed on anything else.
  bool peer_allowed(const std::string& address) const {
    if (allow_.empty()) return true;
    sockaddr_storage ss{};
    if (address.find(':') == std::string::npos) {
      auto* in = reinterpret_cast<sockaddr_in*>(&ss);
      in->sin_family = AF_INET;
      if (inet_pton(AF_INET, address.c_str(), &in->sin_addr) != 1) return false;
    } else {
      auto* in6 = reinterpret_cast<sockaddr_in6*>(&ss);
      in6->sin6_family = AF_INET6;
      const std::string bare = address.substr(0, address.find('%'));  // a link-local scope
      if (inet_pton(AF_INET6, bare.c_str(), &in6->sin6_addr) != 1) return false;
    }
    return allow_.allows(reinterpret_cast<const sockaddr*>(&ss));
  }

  // cpp-httplib 0.11 listens with a backlog of 5: a browser's burst of connections overflows it
  // whenever this low-priority thread is slow to accept, and each dropped SYN costs a second.
  // listen() again on the bound socket sets the backlog anew.
  bool set_backlog(int backlog) { return ::listen(svr_sock_, backlog) == 0; }

  // Connections still queued are closed unserved; those being served are shut down (their worker
  // sees the end of the stream at once). Not undone: a stopped Http is destroyed.
  void close_connections() {
    std::lock_guard lock(mutex_);
    closing_ = true;
    for (const int fd : open_) ::shutdown(fd, SHUT_RDWR);
  }

 private:
  bool process_and_close_socket(socket_t sock) override {
    const Clock::time_point started = Clock::now();
    UniqueFd fd(sock);
    ::fcntl(sock, F_SETFD, FD_CLOEXEC);  // cpp-httplib's accept() does not ask for it
    {
      std::lock_guard lock(mutex_);
      if (closing_) return false;
      open_.push_back(sock);
    }
    bool ok = false;
    try {
      BoundedStream stream(sock, started);
      bool connection_closed = false;
      ok = process_request(stream, /*close_connection=*/true, connection_closed, nullptr);
    } catch (...) {  // std::bad_alloc, std::regex_error: this connection fails, the server goes on
      ok = false;
    }
    linger(sock, started);
    {
      std::lock_guard lock(mutex_);
      std::erase(open_, sock);
    }
    return ok;  // `fd` closes the socket, after it has left open_ (so its number is never shut down reused)
  }

  // A response can be refused before the request's body was read (405, 403); closing a socket
  // with unread bytes sends a reset that can destroy the response on its way to the peer. So: end
  // our side, then read and drop what the peer still sends for a moment.
  static void linger(int fd, Clock::time_point started) {
    ::shutdown(fd, SHUT_WR);
    const Clock::time_point until =
        std::min(Clock::now() + std::chrono::milliseconds(250), started + WebServer::kConnectionDeadline);
    std::array<char, 4096> scratch;
    std::size_t dropped = 0;
    while (dropped < 64 * 1024 && wait_for(fd, POLLIN, until)) {
      const ssize_t n = ::recv(fd, scratch.data(), scratch.size(), MSG_DONTWAIT);
      if (n == 0 || (n < 0 && errno != EINTR && errno != EAGAIN)) return;
      if (n > 0) dropped += static_cast<std::size_t>(n);
    }
  }

  motion::IpAllowList allow_;
  std::mutex mutex_;
  std::vector<int> open_;  // sockets being served
  bool closing_ = false;
};

WebServer::WebServer(WebSettings settings, WebData& data, fs::path web_root)
    : settings_(std::move(settings)), data_(data), web_root_(std::move(web_root)) {}

WebServer::~WebServer() { stop(); }

void WebServer::start() {
  if (thread_.joinable()) throw std::logic_error("web server: already started");
  const std::string& address = settings_.bind_address;
  const std::string where =
      (address.find(':') != std::string::npos ? "[" + address + "]" : address) + ":" + std::to_string(settings_.port);
  in6_addr scratch;
  if (inet_pton(AF_INET, address.c_str(), &scratch) != 1 && inet_pton(AF_INET6, address.c_str(), &scratch) != 1)
    throw std::runtime_error("web: cannot listen on " + where + ": not a numeric IPv4 or IPv6 address");

  auto http = std::make_unique<Http>(motion::IpAllowList(settings_.allow_list));
  Http& h = *http;

  // Limits. BoundedStream applies the timeouts; these are cpp-httplib's own, set alike.
  h.new_task_queue = [] { return new BoundedPool(kWorkers, kQueued); };
  h.set_payload_max_length(kMaxBodyBytes);
  h.set_keep_alive_max_count(1);
  h.set_read_timeout(kIoTimeout);
  h.set_write_timeout(kIoTimeout);
  // Not cpp-httplib's default SO_REUSEPORT, which lets a second mfcd bind the same port silently
  // and take half the connections; SO_REUSEADDR only lets a restart bind past TIME_WAIT.
  h.set_socket_options([](socket_t sock) {
    const int one = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    ::fcntl(sock, F_SETFD, FD_CLOEXEC);
  });
  h.set_default_headers({{"Cache-Control", "no-store"},
                         {"X-Content-Type-Options", "nosniff"},
                         {"X-Frame-Options", "DENY"},
                         {"Referrer-Policy", "no-referrer"}});

  // Before any route: who may ask, and how.
  h.set_pre_routing_handler([&h](const httplib::Request& req, httplib::Response& res) {
    if (!h.peer_allowed(req.remote_addr)) {
      send_error(res, 403, "address " + req.remote_addr + " is not in web.allow_list");
      return httplib::Server::HandlerResponse::Handled;
    }
    // Read-only: GET, and HEAD (GET without the body). WebSettings::allow_control will admit the
    // control endpoints' methods once there are some; there are none yet, so it changes nothing.
    if (req.method != "GET" && req.method != "HEAD") {
      res.set_header("Allow", "GET, HEAD");
      send_error(res, 405, "method " + req.method + " not allowed: this view is read-only");
      return httplib::Server::HandlerResponse::Handled;
    }
    // Several ranges make cpp-httplib 0.11 build a multipart copy of the body per range in memory.
    if (req.ranges.size() > 1) {
      send_error(res, 416, "one byte range per request");
      return httplib::Server::HandlerResponse::Handled;
    }
    return httplib::Server::HandlerResponse::Unhandled;
  });
  // Errors cpp-httplib answers by itself (404, 400, 413, ...) get a JSON body too.
  h.set_error_handler(httplib::Server::HandlerWithResponse([](const httplib::Request&, httplib::Response& res) {
    if (!res.body.empty()) return httplib::Server::HandlerResponse::Unhandled;
    send_error(res, res.status, status_text(res.status));
    return httplib::Server::HandlerResponse::Handled;
  }));
  h.set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
    std::string what = "unknown exception";
    try {
      std::rethrow_exception(ep);
    } catch (const std::exception& e) {
      what = e.what();
    } catch (...) {
    }
    send_error(res, 500, what);
  });

  // The page: three fixed files, read from web_root on each request (nothing else of it is served).
  const auto page_file = [this](const std::string& name) {
    return [this, name](const httplib::Request&, httplib::Response& res) {
      std::ifstream in(web_root_ / name, std::ios::binary);
      std::ostringstream body;
      body << in.rdbuf();
      if (!in) return send_error(res, 404, name + " not found in the web root " + web_root_.string());
      res.set_content(body.str(), mime_of(name));
      if (name == "index.html")
        res.set_header("Content-Security-Policy",
                       "default-src 'self'; img-src 'self'; connect-src 'self'; frame-ancestors 'none'");
    };
  };
  h.Get("/", page_file("index.html"));
  for (const char* name : {"index.html", "app.js", "style.css"}) h.Get(std::string("/") + name, page_file(name));

  h.Get("/api/status", [this](const httplib::Request&, httplib::Response& res) { send_json(res, data_.status()); });
  h.Get("/api/last", [this](const httplib::Request&, httplib::Response& res) { send_json(res, data_.last_cycle()); });
  h.Get("/api/stats", [this](const httplib::Request&, httplib::Response& res) { send_json(res, data_.stats()); });
  h.Get("/api/snapshots",
        [this](const httplib::Request&, httplib::Response& res) { send_json(res, data_.snapshots()); });
  // ?cycle=N is the page's cache buster; the image is always the last cycle's.
  h.Get(R"(/api/image/(ambient|edges|overlay)\.png)", [this](const httplib::Request& req, httplib::Response& res) {
    const std::string name = req.matches[1];
    std::string png;
    if (!data_.image_png(name, png) || png.empty()) return send_error(res, 404, "no " + name + " image yet");
    res.body = std::move(png);
    res.set_header("Content-Type", "image/png");
  });
  // The path is URL-decoded before it is matched, so an encoded '/' cannot cross a component.
  h.Get(R"(/snapshots/([^/]+)/([^/]+))", [this](const httplib::Request& req, httplib::Response& res) {
    const std::string snapshot = req.matches[1], file = req.matches[2];
    if (!safe_component(snapshot) || !safe_component(file))
      return send_error(res, 400, "a snapshot and a file name are [A-Za-z0-9._-], not starting with '.'");
    const fs::path path = data_.snapshot_file(snapshot, file);
    if (path.empty()) return send_error(res, 404, "no file " + file + " in snapshot " + snapshot);
    // Opened once and read by descriptor: the quota may delete the snapshot while it is sent.
    auto fd = std::make_shared<UniqueFd>(::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW));
    struct stat st {};
    if (!*fd || ::fstat(fd->get(), &st) != 0 || !S_ISREG(st.st_mode))
      return send_error(res, 404, "no file " + file + " in snapshot " + snapshot);
    res.set_header("Content-Disposition", "attachment; filename=\"" + file + "\"");
    res.set_content_provider(static_cast<std::size_t>(st.st_size), mime_of(file),
                             [fd](std::size_t offset, std::size_t length, httplib::DataSink& sink) {
                               std::array<char, 64 * 1024> chunk;
                               const ssize_t n = ::pread(fd->get(), chunk.data(), std::min(length, chunk.size()),
                                                         static_cast<off_t>(offset));
                               return n > 0 && sink.write(chunk.data(), static_cast<std::size_t>(n));
                             });
  });

  errno = 0;
  int port = -1;
  if (settings_.port == 0)
    port = h.bind_to_any_port(address);
  else if (h.bind_to_port(address, settings_.port))
    port = settings_.port;
  if (port <= 0) {
    const int err = errno;
    if (err != 0) throw std::system_error(err, std::generic_category(), "web: cannot listen on " + where);
    throw std::runtime_error("web: cannot listen on " + where);
  }

  if (!h.set_backlog(kBacklog))
    throw std::system_error(errno, std::generic_category(), "web: cannot listen on " + where);

  http_ = std::move(http);
  bound_port_ = static_cast<std::uint16_t>(port);
  listen_returned_ = false;
  thread_ = std::thread([this] {
    pthread_setname_np(pthread_self(), "mfcd-web");
    lower_priority_of_this_thread();  // the workers, made by this thread, are lowered again themselves
    try {
      http_->listen_after_bind();
    } catch (...) {  // a worker thread that cannot be made: the view is down, the daemon is not
    }
    listen_returned_ = true;
  });
  // httplib::Server::stop() acts only once the listen loop runs, so start() returns when it does.
  while (!http_->is_running() && !listen_returned_) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  if (!http_->is_running()) {
    thread_.join();
    http_.reset();
    bound_port_ = 0;
    throw std::runtime_error("web: the listen loop on " + where + " ended at once");
  }
}

void WebServer::stop() {
  if (!thread_.joinable()) return;
  http_->close_connections();
  http_->stop();
  thread_.join();
  http_.reset();
  bound_port_ = 0;
}

}  // namespace mfcd::daemon
