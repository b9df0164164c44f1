#pragma once
// Plain syslog with levels; also to stderr when mfcd runs in the foreground. Never called on the
// frame path: the main thread logs a cycle's outcome after it has been published.
// Under journald (stderr connected to the journal, see journal_log.hpp) lines logged with
// log_structured() go to the journal as native entries with structured fields instead.
namespace mfcd::daemon {

class JournalFields;

enum class LogLevel { Error = 3, Warning = 4, Notice = 5, Info = 6, Debug = 7 };  // syslog values
const char* to_string(LogLevel l);

// Opens syslog; and the journal sink on kJournalSocket when stderr is the journal
// (stderr_is_journal()), closes it otherwise. Call before other threads log.
void log_open(const char* ident, bool to_stderr, LogLevel level);
void log_set_level(LogLevel level);
bool log_enabled(LogLevel level);
void logf(LogLevel level, const char* format, ...) __attribute__((format(printf, 2, 3)));

// Points the journal sink at `socket_path` (nullptr: closes it, lines go the plain way). log_open
// does this itself; tests and tools use it to send to a socket of their own. Call before other
// threads log. False (and the sink closed) when no socket could be made.
bool log_open_journal(const char* socket_path);
bool log_to_journal();  // the journal sink is open

// One line with structured fields (journal_log.hpp: journal_entry). Sink open: one journal entry,
// nothing on syslog or stderr (both end in the same journal under systemd); when the send fails
// (journald gone, its queue full) the line takes the plain path. Sink closed: exactly
// logf(level, "%s", message). No heap allocation on the journal path.
void log_structured(LogLevel level, const JournalFields& extra, const char* message);

}  // namespace mfcd::daemon
