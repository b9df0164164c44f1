// The journald sink: $JOURNAL_STREAM detection, journal fields, the native-protocol datagram and
// its sender, and the cycle result line (journal_log.hpp).
#include "daemon/journal_log.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstdarg>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>

namespace mfcd::daemon {

namespace {

// One unsigned decimal number filling [first, last) exactly: no sign, no blanks, no rest.
bool parse_decimal(const char* first, const char* last, std::uint64_t& value) {
  if (first == last) return false;
  const auto [end, ec] = std::from_chars(first, last, value, 10);
  return ec == std::errc() && end == last;
}

bool is_control(char c) {
  const auto u = static_cast<unsigned char>(c);
  return u < 0x20 || u == 0x7f;
}

}  // namespace

bool journal_stream_matches(const char* journal_stream, int fd) {
  if (!journal_stream) return false;
  const char* end = journal_stream + std::strlen(journal_stream);
  const char* colon = std::strchr(journal_stream, ':');
  if (!colon) return false;
  std::uint64_t dev = 0, ino = 0;
  if (!parse_decimal(journal_stream, colon, dev) || !parse_decimal(colon + 1, end, ino)) return false;
  struct stat st {};
  if (::fstat(fd, &st) != 0) return false;
  // systemd prints st_dev and st_ino as plain unsigned decimals (DEV_FMT, INO_FMT).
  return static_cast<std::uint64_t>(st.st_dev) == dev && static_cast<std::uint64_t>(st.st_ino) == ino;
}

bool stderr_is_journal() { return journal_stream_matches(std::getenv("JOURNAL_STREAM"), STDERR_FILENO); }

bool journal_field_name_valid(std::string_view name) {
  // journald's limit (JOURNAL_FIELD_NAME_MAX is 64) and its character set for client fields.
  if (name.empty() || name.size() > 64) return false;
  if (name.front() == '_' || (name.front() >= '0' && name.front() <= '9')) return false;
  for (const char c : name)
    if (!((c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_')) return false;
  return true;
}

bool JournalFields::add(std::string_view name, std::string_view value) {
  if (!journal_field_name_valid(name)) return false;
  const std::size_t needed = name.size() + 1 + value.size();
  if (count_ == kMaxFields || needed > kCapacity - used_) return false;
  char* p = text_ + used_;
  std::memcpy(p, name.data(), name.size());
  p[name.size()] = '=';
  char* v = p + name.size() + 1;
  for (std::size_t i = 0; i < value.size(); ++i) v[i] = is_control(value[i]) ? ' ' : value[i];
  offset_[count_] = used_;
  length_[count_] = needed;
  used_ += needed;
  ++count_;
  return true;
}

bool JournalFields::addf(std::string_view name, const char* format, ...) {
  char value[256];
  va_list args;
  va_start(args, format);
  const int n = std::vsnprintf(value, sizeof value, format, args);
  va_end(args);
  if (n < 0) return false;
  return add(name, std::string_view(value, std::min<std::size_t>(static_cast<std::size_t>(n), sizeof value - 1)));
}

void journal_entry(LogLevel level, const char* ident, std::string_view message, const JournalFields& extra,
                   JournalFields& out) {
  out.clear();
  out.add("MESSAGE", message.substr(0, 1023));
  out.addf("PRIORITY", "%d", static_cast<int>(level));
  out.add("SYSLOG_FACILITY", "3");  // LOG_DAEMON >> 3
  out.add("SYSLOG_IDENTIFIER", ident ? ident : "mfcd");
  for (std::size_t i = 0; i < extra.size(); ++i) {
    const std::string_view f = extra[i];
    const std::size_t eq = f.find('=');  // always there: add() wrote it
    out.add(f.substr(0, eq), f.substr(eq + 1));
  }
}

std::size_t encode_journal_datagram(const JournalFields& fields, char* out, std::size_t capacity) {
  if (fields.size() == 0) return 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < fields.size(); ++i) {
    // NAME=value\n: the name is valid and the value free of newlines by JournalFields::add.
    const std::string_view f = fields[i];
    if (f.size() + 1 > capacity - n) return 0;
    std::memcpy(out + n, f.data(), f.size());
    n += f.size();
    out[n++] = '\n';
  }
  return n;
}

JournalSink::JournalSink(const char* socket_path) {
  const std::size_t len = std::strlen(socket_path);
  if (len == 0 || len >= sizeof addr_.sun_path)
    throw std::runtime_error(std::string("journal socket path does not fit sockaddr_un: ") + socket_path);
  addr_.sun_family = AF_UNIX;
  std::memcpy(addr_.sun_path, socket_path, len + 1);
  addr_len_ = static_cast<socklen_t>(offsetof(sockaddr_un, sun_path) + len + 1);
  fd_.reset(::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0));
  if (!fd_) throw std::runtime_error(std::string("journal socket: ") + std::strerror(errno));
}

bool JournalSink::send(const JournalFields& entry) const {
  char datagram[kMaxDatagram];
  const std::size_t n = encode_journal_datagram(entry, datagram, sizeof datagram);
  if (n == 0) {
    errno = EINVAL;  // an empty entry
    return false;
  }
  const ssize_t sent = ::sendto(fd_.get(), datagram, n, MSG_DONTWAIT | MSG_NOSIGNAL,
                                reinterpret_cast<const sockaddr*>(&addr_), addr_len_);
  return sent == static_cast<ssize_t>(n);
}

}  // namespace mfcd::daemon
