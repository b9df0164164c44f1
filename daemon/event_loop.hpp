#pragma once
// The main thread's poll() loop: sources register a descriptor and what to do when it is
// readable (and, while they have output waiting, writable), instead of the loop knowing every
// descriptor by index. Callbacks may add and remove sources (a control client closing, a cell
// rebuilt by a reload); a source removed during a round is not called for the rest of it.
#include <functional>
#include <vector>

#include <poll.h>

namespace mfcd::daemon {

class EventLoop {
 public:
  using Callback = std::function<void()>;

  // Watches fd for readability (and errors). Registering an fd again replaces its callback.
  // A negative fd is ignored.
  void add(int fd, Callback on_readable);
  // While on_writable is set, also watches fd (already added) for writability; an empty
  // callback stops that. Ignored for an fd not added.
  void on_writable(int fd, Callback on_writable);
  void remove(int fd);
  bool watches(int fd) const;
  std::size_t size() const { return sources_.size(); }

  // Waits up to timeout_ms (-1: until a source is ready) and calls each ready source in the
  // order of registration. Returns false when poll() itself failed (errno set); EINTR is not
  // a failure.
  bool run_once(int timeout_ms);

 private:
  struct Source {
    int fd;
    Callback on_readable;
    Callback on_writable;  // empty: not watched for writability
  };
  Source* find(int fd);
  std::vector<Source> sources_;
  std::vector<pollfd> fds_;  // this round's poll set, rebuilt from sources_
};

}  // namespace mfcd::daemon
