#pragma once
// The journald sink of mfcd's log: when mfcd runs under systemd with its stderr connected to the
// journal, each cycle's result line goes to journald as one native-protocol datagram that carries,
// besides MESSAGE and PRIORITY, structured fields (MFCD_CYCLE, MFCD_JOB_ID, MFCD_ERROR_CODE,
// MFCD_PART, MFCD_SCORE), so `journalctl -u mfcd MFCD_ERROR_CODE=2` selects the failed cycles.
// Anywhere else (a terminal, a pipe, the tests) the line is written exactly as before: syslog, and
// stderr in the foreground (daemon/log.cpp).
//
// Why a sender of our own rather than sd_journal_sendv: libsystemd always sends to
// /run/systemd/journal/socket; this one takes the socket path, so the tests check the very bytes
// against a socket they bind. The protocol is journald's native one (systemd's "Native Journal
// Protocol"): one AF_UNIX datagram of `NAME=value\n` fields (its binary form, `NAME\n` + 64-bit
// little-endian length + value + `\n`, is for values that hold a newline; ours never do).
//
// Real-time: nothing here runs on the frame path. The cycle line is logged by the main thread
// (Daemon::on_result) after the vision worker has handed the result over the SPSC ring. Even so the
// journal path allocates nothing (fixed buffers on the stack) and never blocks: the datagram is
// sent with MSG_DONTWAIT, and when journald's queue is full (or journald is gone) the line falls
// back to the plain path.
#include <sys/socket.h>
#include <sys/un.h>

#include <array>
#include <cstddef>
#include <string_view>

#include "base/unique_fd.hpp"
#include "daemon/log.hpp"

namespace mfcd::daemon {

struct CycleResult;

// journald's native socket (systemd.journal-fields(7), sd_journal_print(3)).
inline constexpr const char* kJournalSocket = "/run/systemd/journal/socket";

// True when `journal_stream`, the value of $JOURNAL_STREAM ("<device>:<inode>", both decimal, as
// systemd.exec(5) describes it), names the file behind `fd`: systemd sets the variable when it
// connects a service's stdout/stderr to the journal, and a child whose stderr was redirected
// elsewhere inherits the variable but no longer matches. Null, empty or malformed values, and a
// descriptor fstat cannot read, give false.
bool journal_stream_matches(const char* journal_stream, int fd);

// journal_stream_matches(getenv("JOURNAL_STREAM"), STDERR_FILENO): how systemd's own tools decide
// that their stderr is the journal.
bool stderr_is_journal();

// A journal field name as journald accepts it from a client: 1..64 characters of A-Z, 0-9 and
// '_', not starting with '_' (those are journald's trusted fields) nor with a digit.
bool journal_field_name_valid(std::string_view name);

// A fixed-capacity list of journal fields, each stored as "NAME=value" (the iovec form of
// sd_journal_sendv). Built without heap allocation. Values are sanitised on the way in: every
// control character (newline, carriage return, tab, ...; bytes < 0x20 and 0x7f) becomes a space, so
// one field is one line in `journalctl -o verbose` and in the plain log.
class JournalFields {
 public:
  static constexpr std::size_t kMaxFields = 16;
  static constexpr std::size_t kCapacity = 2048;  // bytes of "NAME=value" text, all fields together

  // Appends NAME=value. False (and nothing appended) when the name is not valid or the field does
  // not fit; a value longer than the room left is not cut, the field is dropped.
  bool add(std::string_view name, std::string_view value);
  // Appends NAME=<printf result> (formatted into a 256-byte stack buffer; longer results are
  // cut there). Same return as add().
  bool addf(std::string_view name, const char* format, ...) __attribute__((format(printf, 3, 4)));

  std::size_t size() const { return count_; }
  // The i-th field as "NAME=value"; i < size().
  std::string_view operator[](std::size_t i) const { return {text_ + offset_[i], length_[i]}; }
  void clear() { count_ = used_ = 0; }

 private:
  char text_[kCapacity];
  std::array<std::size_t, kMaxFields> offset_{};
  std::array<std::size_t, kMaxFields> length_{};
  std::size_t count_ = 0;
  std::size_t used_ = 0;
};

// The structured fields of one cycle result (Kind::Cycle), in this order:
//   MFCD_CYCLE       the daemon's cycle number (CycleRequest::cycle_id)
//   MFCD_JOB_ID      the PLC's job id (control-socket cycles: 0; continuous mode: its own counter)
//   MFCD_ERROR_CODE  the ERROR_CODE published to the PLC (CycleError; 0 = none)
//   MFCD_PART        the picked part's obj id (template database object id); only with a pick
//   MFCD_SCORE       the pick's score, 0..1, three decimals like the line; only with a pick
// An error result or a cycle without a pick has no MFCD_PART and no MFCD_SCORE, so
// `journalctl MFCD_PART=4` lists the picks of part 4. `out` is cleared first.
void cycle_journal_fields(const CycleResult& result, JournalFields& out);

// The whole journal entry of a log line: MESSAGE (cut at 1023 bytes, like logf's line), PRIORITY
// (the syslog level, 3 error .. 7 debug), SYSLOG_FACILITY=3 (daemon, as openlog(LOG_DAEMON)),
// SYSLOG_IDENTIFIER (`ident`, the name openlog got), then `extra` in its order. `out` is cleared
// first.
void journal_entry(LogLevel level, const char* ident, std::string_view message, const JournalFields& extra,
                   JournalFields& out);

// Encodes `fields` as one native-protocol datagram into out[0..capacity): each field as its
// "NAME=value" and a newline. Returns the length, or 0 when there is no field or it does not fit.
// (The protocol's binary form, for values holding a newline, is never needed: JournalFields
// sanitises every value.)
std::size_t encode_journal_datagram(const JournalFields& fields, char* out, std::size_t capacity);

// Sends entries to a journald native socket: one unconnected AF_UNIX datagram socket, addressed
// per send, so a journald restart is survived without reconnecting. Thread-safe (no shared state
// but the descriptor); no allocation per send.
class JournalSink {
 public:
  // The largest datagram send() makes: a full JournalFields, one newline per field.
  static constexpr std::size_t kMaxDatagram = JournalFields::kCapacity + JournalFields::kMaxFields;

  // `socket_path`: kJournalSocket, or a socket a test bound. Throws std::runtime_error when the
  // path does not fit sockaddr_un or no socket can be made.
  explicit JournalSink(const char* socket_path = kJournalSocket);
  JournalSink(const JournalSink&) = delete;
  JournalSink& operator=(const JournalSink&) = delete;

  // One datagram, MSG_DONTWAIT. False when it cannot be encoded or sent (no journald, queue full:
  // EAGAIN); errno is then set. Never blocks.
  bool send(const JournalFields& entry) const;

 private:
  UniqueFd fd_;
  sockaddr_un addr_{};
  socklen_t addr_len_ = 0;
};

// Logs one cycle's result line (the daemon's main thread, Daemon::on_result): error (LogLevel::Error),
// pick (Info) or no pick (Notice), the same text as always. Through journald with
// cycle_journal_fields() when log.hpp's journal sink is open (log_open found stderr to be the journal),
// else the plain path of logf().
void log_cycle_result(const CycleResult& result);

}  // namespace mfcd::daemon
