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

const char* toString(LogLevel l) {
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
std::atomic<int> gLevel{LOG_INFO};
std::atomic<bool> gStderr{true};
char gIdent[64] = "mfcd";                 // openlog keeps the pointer: static storage
std::unique_ptr<JournalSink> gJournal;    // set before other threads log (logOpen, logOpenJournal)
std::atomic<bool> gJournalFailed{false};  // a send failed once: said once, not per line

// The plain path: syslog, and stderr in the foreground.
void plainLine(int prio, const char* line) {
  syslog(prio, "%s", line);
  if (gStderr) std::fprintf(stderr, "mfcd[%s]: %s\n", toString(static_cast<LogLevel>(prio)), line);
}
}  // namespace

void logOpen(const char* ident, bool toStderr, LogLevel level) {
  std::snprintf(gIdent, sizeof gIdent, "%s", ident);
  // LOG_PERROR would duplicate to stderr too, but without the level; we print our own line.
  openlog(gIdent, LOG_PID | LOG_NDELAY, LOG_DAEMON);
  gStderr = toStderr;
  gLevel = static_cast<int>(level);
  logOpenJournal(stderrIsJournal() ? kJournalSocket : nullptr);
}

void logSetLevel(LogLevel level) { gLevel = static_cast<int>(level); }

bool logEnabled(LogLevel level) { return static_cast<int>(level) <= gLevel.load(); }

void logf(LogLevel level, const char* format, ...) {
  const int prio = static_cast<int>(level);
  if (prio > gLevel.load()) return;
  char line[1024];
  va_list args;
  va_start(args, format);
  std::vsnprintf(line, sizeof line, format, args);
  va_end(args);
  plainLine(prio, line);
}

bool logOpenJournal(const char* socketPath) {
  gJournal.reset();
  gJournalFailed = false;
  if (!socketPath) return true;
  try {
    gJournal = std::make_unique<JournalSink>(socketPath);
    return true;
  } catch (const std::exception& e) {
    logf(LogLevel::Warning, "%s; structured journal fields are off", e.what());
    return false;
  }
}

bool logToJournal() { return gJournal != nullptr; }

void logStructured(LogLevel level, const JournalFields& extra, const char* message) {
  const int prio = static_cast<int>(level);
  if (prio > gLevel.load()) return;
  if (gJournal) {
    JournalFields entry;
    journalEntry(level, gIdent, message, extra, entry);
    if (gJournal->send(entry)) return;
    const int error = errno;
    if (!gJournalFailed.exchange(true)) {
      char why[160];
      std::snprintf(why, sizeof why,
                    "journal: a structured entry could not be sent (%s); such lines go to syslog without fields",
                    std::strerror(error));
      plainLine(LOG_WARNING, why);
    }
  }
  // Sink closed, or the datagram could not go: the line as logf writes it (same 1023-byte cut).
  char line[1024];
  std::snprintf(line, sizeof line, "%s", message);
  plainLine(prio, line);
}

}  // namespace mfcd::daemon
