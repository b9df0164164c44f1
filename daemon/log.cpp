#include "daemon/log.hpp"

#include <syslog.h>

#include <atomic>
#include <cerrno>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>

#include "daemon/journal_log.hpp"

namespace mfcd::daemon {

const char* to_string(LogLevel l) {
  switch (l) {
    case LogLevel::Error:
      return "error";
    case LogLevel::Warning:
      return "warning";
    case LogLevel::Notice:
      return "notice";
    case LogLevel::Info:
      return "info";
    case LogLevel::Debug:
      return "debug";
  }
  return "?";
}

namespace {
std::atomic<int> g_level{LOG_INFO};
std::atomic<bool> g_stderr{true};
char g_ident[64] = "mfcd";                  // openlog keeps the pointer: static storage
std::unique_ptr<JournalSink> g_journal;     // set before other threads log (log_open, log_open_journal)
std::atomic<bool> g_journal_failed{false};  // a send failed once: said once, not per line

// The plain path: syslog, and stderr in the foreground.
void plain_line(int prio, const char* line) {
  syslog(prio, "%s", line);
  if (g_stderr) std::fprintf(stderr, "mfcd[%s]: %s\n", to_string(static_cast<LogLevel>(prio)), line);
}
}  // namespace

void log_open(const char* ident, bool to_stderr, LogLevel level) {
  std::snprintf(g_ident, sizeof g_ident, "%s", ident);
  // LOG_PERROR would duplicate to stderr too, but without the level; we print our own line.
  openlog(g_ident, LOG_PID | LOG_NDELAY, LOG_DAEMON);
  g_stderr = to_stderr;
  g_level = static_cast<int>(level);
  log_open_journal(stderr_is_journal() ? kJournalSocket : nullptr);
}

void log_set_level(LogLevel level) { g_level = static_cast<int>(level); }

bool log_enabled(LogLevel level) { return static_cast<int>(level) <= g_level.load(); }

void logf(LogLevel level, const char* format, ...) {
  const int prio = static_cast<int>(level);
  if (prio > g_level.load()) return;
  char line[1024];
  va_list args;
  va_start(args, format);
  std::vsnprintf(line, sizeof line, format, args);
  va_end(args);
  plain_line(prio, line);
}

bool log_open_journal(const char* socket_path) {
  g_journal.reset();
  g_journal_failed = false;
  if (!socket_path) return true;
  try {
    g_journal = std::make_unique<JournalSink>(socket_path);
    return true;
  } catch (const std::exception& e) {
    logf(LogLevel::Warning, "%s; structured journal fields are off", e.what());
    return false;
  }
}

bool log_to_journal() { return g_journal != nullptr; }

void log_structured(LogLevel level, const JournalFields& extra, const char* message) {
  const int prio = static_cast<int>(level);
  if (prio > g_level.load()) return;
  if (g_journal) {
    JournalFields entry;
    journal_entry(level, g_ident, message, extra, entry);
    if (g_journal->send(entry)) return;
    const int error = errno;
    if (!g_journal_failed.exchange(true)) {
      char why[160];
      std::snprintf(why, sizeof why,
                    "journal: a structured entry could not be sent (%s); such lines go to syslog without fields",
                    std::strerror(error));
      plain_line(LOG_WARNING, why);
    }
  }
  // Sink closed, or the datagram could not go: the line as logf writes it (same 1023-byte cut).
  char line[1024];
  std::snprintf(line, sizeof line, "%s", message);
  plain_line(prio, line);
}

}  // namespace mfcd::daemon
