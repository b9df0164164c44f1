#include "daemon/event_loop.hpp"

#include <algorithm>
#include <cerrno>

namespace mfcd::daemon {

void EventLoop::add(int fd, Callback on_readable) {
  if (fd < 0) return;
  for (Source& s : sources_)
    if (s.fd == fd) {
      s.on_readable = std::move(on_readable);
      return;
    }
  sources_.push_back({fd, std::move(on_readable), {}});
}

void EventLoop::on_writable(int fd, Callback on_writable) {
  if (Source* s = find(fd)) s->on_writable = std::move(on_writable);
}

EventLoop::Source* EventLoop::find(int fd) {
  const auto it = std::find_if(sources_.begin(), sources_.end(), [fd](const Source& s) { return s.fd == fd; });
  return it == sources_.end() ? nullptr : &*it;
}

void EventLoop::remove(int fd) {
  std::erase_if(sources_, [fd](const Source& s) { return s.fd == fd; });
}

bool EventLoop::watches(int fd) const {
  return std::any_of(sources_.begin(), sources_.end(), [fd](const Source& s) { return s.fd == fd; });
}

bool EventLoop::run_once(int timeout_ms) {
  fds_.clear();
  for (const Source& s : sources_)
    fds_.push_back({s.fd, static_cast<short>(s.on_writable ? POLLIN | POLLOUT : POLLIN), 0});
  const int n = ::poll(fds_.data(), fds_.size(), timeout_ms);
  if (n < 0) return errno == EINTR;
  for (const pollfd& p : fds_) {
    if (!p.revents) continue;
    // Found by fd, not by index: earlier callbacks of this round may have changed the sources.
    // Copied before the call: a callback may remove its own source. Errors and hang-ups go to
    // the readable callback, which sees them when it reads.
    if (p.revents & ~POLLOUT) {
      const Source* s = find(p.fd);
      if (!s) continue;
      const Callback callback = s->on_readable;
      callback();
    }
    if (p.revents & POLLOUT) {
      const Source* s = find(p.fd);
      if (!s || !s->on_writable) continue;
      const Callback callback = s->on_writable;
      callback();
    }
  }
  return true;
}

}  // namespace mfcd::daemon
