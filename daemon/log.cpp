#include "daemon/log.hpp"

#include <syslog.h>

#include <atomic>
#include <cstdarg>
#include <cstdio>

namespace mfcd::daemon {

const char* toString(LogLevel l) {
  switch (l) {
    case LogLevel::Error: return "error";
    case LogLevel::Warning: return "warning";
    case LogLevel::Notice: return "notice";
    case LogLevel::Info: return "info";
    case LogLevel::Debug: return "debug";
  }
  return "?";
}

namespace {
std::atomic<int> gLevel{LOG_INFO};
std::atomic<bool> gStderr{true};
}  // namespace

void logOpen(const char* ident, bool toStderr, LogLevel level) {
  // LOG_PERROR would duplicate to stderr too, but without the level; we print our own line.
  openlog(ident, LOG_PID | LOG_NDELAY, LOG_DAEMON);
  gStderr = toStderr;
  gLevel = static_cast<int>(level);
}

void logSetLevel(LogLevel level) { gLevel = static_cast<int>(level); }

void logf(LogLevel level, const char* format, ...) {
  const int prio = static_cast<int>(level);
  if (prio > gLevel.load()) return;
  char line[1024];
  va_list args;
  va_start(args, format);
  std::vsnprintf(line, sizeof line, format, args);
  va_end(args);
  syslog(prio, "%s", line);
  if (gStderr) std::fprintf(stderr, "mfcd[%s]: %s\n", toString(level), line);
}

}  // namespace mfcd::daemon
