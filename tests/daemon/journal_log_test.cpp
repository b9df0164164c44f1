// The journald sink (daemon/journal_log.hpp): $JOURNAL_STREAM detection against real descriptors,
// the exact fields and datagram made for a cycle result, the bytes that arrive on an AF_UNIX
// datagram socket the test binds, the plain line kept without a journal, the fallback when
// journald is gone or its queue is full, no allocation on the journal path; and a round trip through
// a real systemd-journald read back with journalctl (skipped where none can run).
#include <gtest/gtest.h>

#include <fcntl.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "../hal/alloc_counter.hpp"
#include "daemon/journal_log.hpp"
#include "journal_samples.hpp"

using namespace mfcd::daemon;
using namespace mfcd::daemon::test;
namespace fs = std::filesystem;
using Fields = std::vector<std::string>;

namespace {

// A fresh directory under the temporary directory, removed at the end.
class TempDir {
 public:
  TempDir() {
    std::string t = (fs::temp_directory_path() / "mfcd-journal-XXXXXX").string();
    if (!::mkdtemp(t.data())) throw std::runtime_error("mkdtemp failed");
    path_ = t;
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

std::string dev_ino(int fd) {
  struct stat st {};
  if (::fstat(fd, &st) != 0) return "";
  return std::to_string(static_cast<unsigned long long>(st.st_dev)) + ":" +
         std::to_string(static_cast<unsigned long long>(st.st_ino));
}

// The journal's end of the native protocol: an AF_UNIX datagram socket bound at `path`.
class FakeJournal {
 public:
  explicit FakeJournal(const fs::path& path) : path_(path) {
    fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::strncpy(addr.sun_path, path.c_str(), sizeof addr.sun_path - 1);
    if (fd_ < 0 || ::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0)
      throw std::runtime_error("cannot bind " + path.string());
  }
  ~FakeJournal() { ::close(fd_); }
  // The next datagram, or nullopt when none arrives within `timeout_ms`.
  std::optional<std::string> receive(int timeout_ms = 2000) {
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, timeout_ms) != 1) return std::nullopt;
    char buf[65536];
    const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
    if (n < 0) return std::nullopt;
    return std::string(buf, static_cast<std::size_t>(n));
  }
  int fd() const { return fd_; }

 private:
  fs::path path_;
  int fd_ = -1;
};

// Parses a native-protocol datagram of NAME=value lines, as journald does, strictly: every line
// ends with '\n', has a '=' and a valid upper-case name. Failures are test failures.
std::vector<std::pair<std::string, std::string>> parse_datagram(const std::string& d) {
  std::vector<std::pair<std::string, std::string>> out;
  std::size_t pos = 0;
  while (pos < d.size()) {
    const std::size_t nl = d.find('\n', pos);
    if (nl == std::string::npos) {
      ADD_FAILURE() << "datagram does not end with a newline: " << d.substr(pos);
      break;
    }
    const std::string line = d.substr(pos, nl - pos);
    const std::size_t eq = line.find('=');
    if (eq == std::string::npos) {
      ADD_FAILURE() << "line without '=' (the binary form is never sent): " << line;
    } else {
      const std::string name = line.substr(0, eq);
      EXPECT_TRUE(journal_field_name_valid(name)) << name;
      for (const char c : name) EXPECT_TRUE((c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_') << name;
      out.emplace_back(name, line.substr(eq + 1));
    }
    pos = nl + 1;
  }
  return out;
}

std::map<std::string, std::string> as_map(const std::vector<std::pair<std::string, std::string>>& fields) {
  std::map<std::string, std::string> m;
  for (const auto& [k, v] : fields) {
    EXPECT_EQ(m.count(k), 0u) << "field " << k << " twice";
    m[k] = v;
  }
  return m;
}

Fields as_strings(const JournalFields& f) {
  Fields out;
  for (std::size_t i = 0; i < f.size(); ++i) out.emplace_back(f[i]);
  return out;
}

// Newlines of a line as the sink writes them into MESSAGE: spaces.
std::string flattened(std::string s) {
  for (char& c : s)
    if (c == '\n') c = ' ';
  return s;
}

// Points fd 2 at a file while alive (and JOURNAL_STREAM at nothing); gives back what was written.
class StderrCapture {
 public:
  StderrCapture() : file_(dir_.path() / "stderr") {
    std::fflush(stderr);
    saved_ = ::dup(STDERR_FILENO);
    const int fd = ::open(file_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
    ::dup2(fd, STDERR_FILENO);
    ::close(fd);
  }
  ~StderrCapture() {
    std::fflush(stderr);
    ::dup2(saved_, STDERR_FILENO);
    ::close(saved_);
  }
  std::string text() const {
    std::fflush(stderr);
    std::ifstream in(file_);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }

 private:
  TempDir dir_;
  fs::path file_;
  int saved_ = -1;
};

// The log as mfcd opens it (stderr on, as with -f), its journal sink on `socket` (nullptr: none).
void open_log(const char* socket) {
  ::unsetenv("JOURNAL_STREAM");
  log_open("mfcd", true, LogLevel::Info);
  ASSERT_FALSE(log_to_journal());
  if (socket) {
    ASSERT_TRUE(log_open_journal(socket));
  }
}

}  // namespace

// ---- $JOURNAL_STREAM detection ----

TEST(JournalStream, MatchesTheDescriptorItNames) {
  TempDir dir;
  const int file = ::open((dir.path() / "f").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0600);
  ASSERT_GE(file, 0);
  EXPECT_TRUE(journal_stream_matches(dev_ino(file).c_str(), file));
  // Another file on the same device: same st_dev, other inode.
  const int other = ::open((dir.path() / "g").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0600);
  EXPECT_FALSE(journal_stream_matches(dev_ino(file).c_str(), other));
  EXPECT_TRUE(journal_stream_matches(dev_ino(other).c_str(), other));
  // A pipe (stderr redirected by a shell): another device and inode.
  int p[2];
  ASSERT_EQ(::pipe2(p, O_CLOEXEC), 0);
  EXPECT_FALSE(journal_stream_matches(dev_ino(file).c_str(), p[1]));
  EXPECT_TRUE(journal_stream_matches(dev_ino(p[1]).c_str(), p[1]));
  // Same inode number on another device, same device with the next inode.
  struct stat st {};
  ASSERT_EQ(::fstat(file, &st), 0);
  const auto dev = static_cast<unsigned long long>(st.st_dev), ino = static_cast<unsigned long long>(st.st_ino);
  EXPECT_FALSE(journal_stream_matches((std::to_string(dev + 1) + ":" + std::to_string(ino)).c_str(), file));
  EXPECT_FALSE(journal_stream_matches((std::to_string(dev) + ":" + std::to_string(ino + 1)).c_str(), file));
  // A closed descriptor cannot be the journal.
  const std::string s = dev_ino(file);
  ::close(file);
  EXPECT_FALSE(journal_stream_matches(s.c_str(), file));
  ::close(other);
  ::close(p[0]);
  ::close(p[1]);
}

TEST(JournalStream, MalformedValuesDoNotMatch) {
  TempDir dir;
  const int file = ::open((dir.path() / "f").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0600);
  ASSERT_GE(file, 0);
  struct stat st {};
  ASSERT_EQ(::fstat(file, &st), 0);
  const std::string dev = std::to_string(static_cast<unsigned long long>(st.st_dev));
  const std::string ino = std::to_string(static_cast<unsigned long long>(st.st_ino));
  ASSERT_TRUE(journal_stream_matches((dev + ":" + ino).c_str(), file));
  EXPECT_FALSE(journal_stream_matches(nullptr, file));
  for (const std::string& bad :
       {std::string(), std::string(":"), dev, dev + ":", ":" + ino, ino + ":" + dev, " " + dev + ":" + ino,
        dev + ":" + ino + " ", dev + ":" + ino + "\n", dev + " :" + ino, "+" + dev + ":" + ino, "-" + dev + ":" + ino,
        dev + ":0x" + ino, dev + ":" + ino + ":0", dev + "/" + ino, "99999999999999999999999:" + ino,
        std::string("a:b")})
    EXPECT_FALSE(journal_stream_matches(bad.c_str(), file)) << "'" << bad << "'";
  ::close(file);
}

// stderr_is_journal and log_open read $JOURNAL_STREAM against the process's real fd 2.
TEST(JournalStream, StderrAndLogOpenFollowTheEnvironment) {
  TempDir dir;
  StderrCapture capture;  // fd 2 is now a file of ours
  const std::string mine = dev_ino(STDERR_FILENO);
  int p[2];
  ASSERT_EQ(::pipe2(p, O_CLOEXEC), 0);

  ::setenv("JOURNAL_STREAM", mine.c_str(), 1);
  EXPECT_TRUE(stderr_is_journal());
  log_open("mfcd", true, LogLevel::Info);
  EXPECT_TRUE(log_to_journal());  // the sink on kJournalSocket (made, not yet used)

  ::setenv("JOURNAL_STREAM", dev_ino(p[1]).c_str(), 1);  // inherited from a parent whose stderr was the journal
  EXPECT_FALSE(stderr_is_journal());
  log_open("mfcd", true, LogLevel::Info);
  EXPECT_FALSE(log_to_journal());

  ::unsetenv("JOURNAL_STREAM");
  EXPECT_FALSE(stderr_is_journal());
  log_open("mfcd", true, LogLevel::Info);
  EXPECT_FALSE(log_to_journal());
  ::close(p[0]);
  ::close(p[1]);
}

// ---- field names and values ----

TEST(JournalFields, NamesAreCheckedAsJournaldDoes) {
  for (const char* good : {"MESSAGE", "MFCD_CYCLE", "MFCD_ERROR_CODE", "A", "X9_", "PRIORITY"})
    EXPECT_TRUE(journal_field_name_valid(good)) << good;
  EXPECT_TRUE(journal_field_name_valid(std::string(64, 'A')));
  for (const std::string& bad :
       {std::string(), std::string("mfcd_cycle"), std::string("Mfcd_Cycle"), std::string("_PID"), std::string("1ABC"),
        std::string("MFCD-CYCLE"), std::string("MFCD CYCLE"), std::string("MFCD=X"), std::string(65, 'A'),
        std::string("MFCD\nX")})
    EXPECT_FALSE(journal_field_name_valid(bad)) << bad;
  JournalFields f;
  EXPECT_FALSE(f.add("mfcd_cycle", "1"));
  EXPECT_FALSE(f.add("_PID", "1"));
  EXPECT_EQ(f.size(), 0u);
}

TEST(JournalFields, ValuesAreSanitisedToOneLine) {
  JournalFields f;
  ASSERT_TRUE(f.add("MESSAGE", "camera failed\nEIO\r\tagain\x7f\x01 end"));
  ASSERT_TRUE(f.add("MFCD_PART", "\xc2\xb5-part"));  // UTF-8 stays as it is
  ASSERT_TRUE(f.addf("MFCD_SCORE", "%.3f", 0.5));
  ASSERT_TRUE(f.add("EMPTY", ""));
  EXPECT_EQ(as_strings(f), (Fields{"MESSAGE=camera failed EIO  again   end", "MFCD_PART=\xc2\xb5-part",
                                   "MFCD_SCORE=0.500", "EMPTY="}));
}

TEST(JournalFields, FullListDropsWholeFields) {
  JournalFields f;
  for (std::size_t i = 0; i < JournalFields::kMaxFields; ++i) ASSERT_TRUE(f.addf("F", "%zu", i));
  EXPECT_FALSE(f.add("G", "1"));
  EXPECT_EQ(f.size(), JournalFields::kMaxFields);
  f.clear();
  EXPECT_EQ(f.size(), 0u);
  const std::string big(JournalFields::kCapacity - 2, 'x');  // "A=" + big fills the capacity exactly
  EXPECT_FALSE(f.add("AB", big));                            // one byte too many: not cut, dropped
  EXPECT_EQ(f.size(), 0u);
  ASSERT_TRUE(f.add("A", big));
  EXPECT_FALSE(f.add("B", ""));
  EXPECT_EQ(f[0].size(), JournalFields::kCapacity);
}

// ---- the fields and datagram of a cycle result ----

TEST(CycleJournalFields, ErrorResult) {
  JournalFields f;
  cycle_journal_fields(error_result(41, 7), f);
  EXPECT_EQ(as_strings(f), (Fields{"MFCD_CYCLE=41", "MFCD_JOB_ID=7", "MFCD_ERROR_CODE=2"}));
  // An error after a pick was chosen (the transform failed) still carries no pick fields.
  CycleResult r = pick_result(44, 9);
  r.error = CycleError::Transform;
  cycle_journal_fields(r, f);
  EXPECT_EQ(as_strings(f), (Fields{"MFCD_CYCLE=44", "MFCD_JOB_ID=9", "MFCD_ERROR_CODE=4"}));
}

TEST(CycleJournalFields, PickResult) {
  JournalFields f;
  cycle_journal_fields(pick_result(18446744073709551615ull, 65535), f);
  EXPECT_EQ(as_strings(f), (Fields{"MFCD_CYCLE=18446744073709551615", "MFCD_JOB_ID=65535", "MFCD_ERROR_CODE=0",
                                   "MFCD_PART=4", "MFCD_SCORE=0.625"}));
}

TEST(CycleJournalFields, ResultWithoutAPick) {
  JournalFields f;
  cycle_journal_fields(no_pick_result(43, 0), f);
  EXPECT_EQ(as_strings(f), (Fields{"MFCD_CYCLE=43", "MFCD_JOB_ID=0", "MFCD_ERROR_CODE=0"}));
}

TEST(CycleJournalFields, WholeEntryAndDatagram) {
  JournalFields extra, entry;
  cycle_journal_fields(error_result(41, 7), extra);
  journal_entry(LogLevel::Error, "mfcd", error_line(41, 7), extra, entry);
  const Fields expected{"MESSAGE=cycle 41 (plc job 7 recipe 2): error 2: camera: VIDIOC_DQBUF failed EIO",
                        "PRIORITY=3",
                        "SYSLOG_FACILITY=3",
                        "SYSLOG_IDENTIFIER=mfcd",
                        "MFCD_CYCLE=41",
                        "MFCD_JOB_ID=7",
                        "MFCD_ERROR_CODE=2"};
  EXPECT_EQ(as_strings(entry), expected);
  char d[JournalSink::kMaxDatagram];
  const std::size_t n = encode_journal_datagram(entry, d, sizeof d);
  std::string bytes;
  for (const auto& f : expected) bytes += f + "\n";
  EXPECT_EQ(std::string(d, n), bytes);
  // Too small a buffer, or nothing to send: 0, never a cut datagram.
  EXPECT_EQ(encode_journal_datagram(entry, d, bytes.size() - 1), 0u);
  EXPECT_EQ(encode_journal_datagram(entry, d, bytes.size()), bytes.size());
  EXPECT_EQ(encode_journal_datagram(JournalFields{}, d, sizeof d), 0u);

  // PRIORITY follows the level; a long message is cut at 1023 bytes like logf's line.
  cycle_journal_fields(pick_result(42, 8), extra);
  journal_entry(LogLevel::Info, "mfcd", std::string(3000, 'm'), extra, entry);
  const Fields got = as_strings(entry);
  ASSERT_EQ(got.size(), 9u);
  EXPECT_EQ(got[0], "MESSAGE=" + std::string(1023, 'm'));
  EXPECT_EQ(got[1], "PRIORITY=6");
  EXPECT_EQ(got[7], "MFCD_PART=4");
  EXPECT_EQ(got[8], "MFCD_SCORE=0.625");
  journal_entry(LogLevel::Notice, "mfcd", "x", extra, entry);
  EXPECT_EQ(entry[1], "PRIORITY=5");
  journal_entry(LogLevel::Warning, "mfcd", "x", extra, entry);
  EXPECT_EQ(entry[1], "PRIORITY=4");
  journal_entry(LogLevel::Debug, "mfcd", "x", extra, entry);
  EXPECT_EQ(entry[1], "PRIORITY=7");
}

// ---- through a socket: the bytes that arrive ----

TEST(JournalSink, OneDatagramArrivesOnTheBoundSocket) {
  TempDir dir;
  FakeJournal journal(dir.path() / "socket");
  JournalSink sink((dir.path() / "socket").c_str());
  JournalFields extra, entry;
  cycle_journal_fields(pick_result(42, 8), extra);
  journal_entry(LogLevel::Info, "mfcd", pick_line(42, 8), extra, entry);
  ASSERT_TRUE(sink.send(entry));
  const auto d = journal.receive();
  ASSERT_TRUE(d);
  char expected[JournalSink::kMaxDatagram];
  EXPECT_EQ(*d, std::string(expected, encode_journal_datagram(entry, expected, sizeof expected)));
  const auto fields = parse_datagram(*d);
  ASSERT_EQ(fields.size(), 9u);
  EXPECT_EQ(fields[0], std::make_pair(std::string("MESSAGE"), pick_line(42, 8)));
  EXPECT_EQ(fields[8], std::make_pair(std::string("MFCD_SCORE"), std::string("0.625")));
  EXPECT_FALSE(journal.receive(50)) << "one entry, one datagram";
}

TEST(JournalSink, RefusesAPathThatDoesNotFit) {
  EXPECT_THROW(JournalSink(std::string(200, 'x').c_str()), std::runtime_error);
  EXPECT_THROW(JournalSink(""), std::runtime_error);
}

// The daemon's own call: log_cycle_result with the sink open sends the three lines as entries
// and writes nothing on stderr (under systemd stderr is the same journal).
TEST(JournalLog, CycleLinesGoToTheJournalWithFields) {
  TempDir dir;
  FakeJournal journal(dir.path() / "socket");
  StderrCapture capture;
  open_log((dir.path() / "socket").c_str());

  log_cycle_result(error_result(41, 7));
  log_cycle_result(pick_result(42, 8));
  log_cycle_result(no_pick_result(43, 9));

  auto d = journal.receive();
  ASSERT_TRUE(d);
  auto m = as_map(parse_datagram(*d));
  EXPECT_EQ(m, (std::map<std::string, std::string>{{"MESSAGE", flattened(error_line(41, 7))},
                                                   {"PRIORITY", "3"},
                                                   {"SYSLOG_FACILITY", "3"},
                                                   {"SYSLOG_IDENTIFIER", "mfcd"},
                                                   {"MFCD_CYCLE", "41"},
                                                   {"MFCD_JOB_ID", "7"},
                                                   {"MFCD_ERROR_CODE", "2"}}));
  d = journal.receive();
  ASSERT_TRUE(d);
  m = as_map(parse_datagram(*d));
  EXPECT_EQ(m["MESSAGE"], pick_line(42, 8));
  EXPECT_EQ(m["PRIORITY"], "6");
  EXPECT_EQ(m["MFCD_CYCLE"], "42");
  EXPECT_EQ(m["MFCD_JOB_ID"], "8");
  EXPECT_EQ(m["MFCD_ERROR_CODE"], "0");
  EXPECT_EQ(m["MFCD_PART"], "4");
  EXPECT_EQ(m["MFCD_SCORE"], "0.625");
  d = journal.receive();
  ASSERT_TRUE(d);
  m = as_map(parse_datagram(*d));
  EXPECT_EQ(m["MESSAGE"], no_pick_line(43, 9));
  EXPECT_EQ(m["PRIORITY"], "5");
  EXPECT_EQ(m.count("MFCD_PART"), 0u);
  EXPECT_EQ(m.count("MFCD_SCORE"), 0u);
  EXPECT_EQ(m.size(), 7u);
  EXPECT_FALSE(journal.receive(50));
  EXPECT_EQ(capture.text(), "");
  log_open_journal(nullptr);
}

// Without a journal the line is written exactly as Daemon::on_result always wrote it.
TEST(JournalLog, PlainLineUnchangedWithoutJournal) {
  TempDir dir;
  FakeJournal journal(dir.path() / "socket");  // bound, but the sink is not pointed at it
  StderrCapture capture;
  open_log(nullptr);
  log_cycle_result(error_result(41, 7));
  log_cycle_result(pick_result(42, 8));
  log_cycle_result(no_pick_result(43, 9));
  EXPECT_EQ(capture.text(),
            "mfcd[error]: cycle 41 (plc job 7 recipe 2): error 2: camera: VIDIOC_DQBUF failed\nEIO\n"
            "mfcd[info]: cycle 42 (plc job 8 recipe 3): pick obj 4 at 512.5 -20.0 130.3 / 180.0 0.0 -35.5 "
            "score 0.625, 3 found, 180 ms\n"
            "mfcd[notice]: cycle 43 (control job 9 recipe 1): no pick, 0 found, 96 ms\n");
  EXPECT_FALSE(journal.receive(50));
}

TEST(JournalLog, LevelFilterApplies) {
  TempDir dir;
  FakeJournal journal(dir.path() / "socket");
  StderrCapture capture;
  open_log((dir.path() / "socket").c_str());
  log_set_level(LogLevel::Warning);
  log_cycle_result(pick_result(42, 8));     // info: filtered
  log_cycle_result(no_pick_result(43, 9));  // notice: filtered
  log_cycle_result(error_result(41, 7));
  const auto d = journal.receive();
  ASSERT_TRUE(d);
  EXPECT_EQ(as_map(parse_datagram(*d))["MFCD_CYCLE"], "41");
  EXPECT_FALSE(journal.receive(50));
  log_set_level(LogLevel::Info);
  log_open_journal(nullptr);
}

// journald stopped (nothing bound at the path): the lines take the plain path; one warning says so.
TEST(JournalLog, FallsBackToThePlainLineWhenJournaldIsGone) {
  TempDir dir;
  StderrCapture capture;
  open_log((dir.path() / "nobody-listens").c_str());
  log_cycle_result(error_result(41, 7));
  log_cycle_result(no_pick_result(43, 9));
  const std::string text = capture.text();
  EXPECT_EQ(text,
            "mfcd[warning]: journal: a structured entry could not be sent (No such file or directory); such lines go "
            "to syslog without fields\n"
            "mfcd[error]: " +
                error_line(41, 7) +
                "\n"
                "mfcd[notice]: " +
                no_pick_line(43, 9) + "\n");
  log_open_journal(nullptr);
}

// journald's queue full: the send does not wait (MSG_DONTWAIT), the line takes the plain path.
TEST(JournalLog, FullQueueNeverBlocks) {
  TempDir dir;
  FakeJournal journal(dir.path() / "socket");  // never read until the end
  JournalSink filler((dir.path() / "socket").c_str());
  JournalFields entry;
  journal_entry(LogLevel::Info, "mfcd", "filler", JournalFields{}, entry);
  int sent = 0;
  while (filler.send(entry) && sent < 1000000) ++sent;
  ASSERT_EQ(errno, EAGAIN) << "after " << sent << " datagrams";
  ASSERT_GT(sent, 0);

  StderrCapture capture;
  open_log((dir.path() / "socket").c_str());
  const auto t0 = std::chrono::steady_clock::now();
  log_cycle_result(error_result(41, 7));
  const auto ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_LT(ms, 500.0);
  const std::string text = capture.text();
  EXPECT_NE(text.find("(Resource temporarily unavailable)"), std::string::npos) << text;
  EXPECT_NE(text.find("mfcd[error]: " + error_line(41, 7) + "\n"), std::string::npos) << text;
  log_open_journal(nullptr);
}

// The journal path formats and sends from fixed buffers: no heap allocation per line.
TEST(JournalLog, JournalPathDoesNotAllocate) {
  TempDir dir;
  FakeJournal journal(dir.path() / "socket");
  StderrCapture capture;
  open_log((dir.path() / "socket").c_str());
  const CycleResult results[] = {error_result(41, 7), pick_result(42, 8), no_pick_result(43, 9)};
  log_cycle_result(results[0]);  // warm-up
  ASSERT_TRUE(journal.receive());
  int received = 0;
  const auto before = mfcd::hal::test::allocation_count();
  for (int i = 0; i < 30; ++i) {
    log_cycle_result(results[i % 3]);
    char buf[4096];  // drain, so the queue never fills
    if (::recv(journal.fd(), buf, sizeof buf, MSG_DONTWAIT) > 0) ++received;
  }
  const auto allocations = mfcd::hal::test::allocation_count() - before;
  EXPECT_EQ(allocations, 0u);
  EXPECT_EQ(received, 30);
  EXPECT_EQ(capture.text(), "");
  log_open_journal(nullptr);
}

// ---- a real journald ----

// The probe logs the three samples under a real systemd-journald (the system's through
// systemd-run, or a private one in a mount namespace; journal_roundtrip.sh); journalctl reads them
// back by their fields.
TEST(JournalRoundTrip, JournalctlSelectsCyclesByTheirFields) {
  const unsigned job = static_cast<unsigned>(::getpid()) % 60000 + 1;
  const unsigned long long cycle = 1000000ull + static_cast<unsigned long long>(::getpid());
  const std::string cmd = std::string("/bin/sh ") + MFCD_JOURNAL_ROUNDTRIP + " " + MFCD_JOURNAL_PROBE + " " +
                          std::to_string(cycle) + " " + std::to_string(job) + " 2>&1";
  FILE* p = ::popen(cmd.c_str(), "r");
  ASSERT_NE(p, nullptr);
  std::string out;
  char buf[4096];
  for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, p)) > 0;) out.append(buf, n);
  const int status = ::pclose(p);
  ASSERT_TRUE(WIFEXITED(status)) << out;
  if (WEXITSTATUS(status) == 77) GTEST_SKIP() << out;
  ASSERT_EQ(WEXITSTATUS(status), 0) << out;

  std::map<std::string, std::vector<nlohmann::json>> sections;
  std::string section, mode;
  std::istringstream lines(out);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("== mode ", 0) == 0)
      mode = line.substr(8);
    else if (line.rfind("== ", 0) == 0)
      section = line.substr(3);
    else if (!line.empty() && line[0] == '{')
      sections[section].push_back(nlohmann::json::parse(line));
  }
  ASSERT_FALSE(mode.empty()) << out;
  std::printf("journald: %s\n", mode.c_str());

  // The three cycle lines, native entries with their fields, in order.
  const auto& entries = sections["entries"];
  ASSERT_EQ(entries.size(), 3u) << out;
  const auto field = [](const nlohmann::json& e, const char* name) {
    return e.contains(name) ? e[name].get<std::string>() : "-";
  };
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(field(entries[i], "_TRANSPORT"), "journal");
    EXPECT_EQ(field(entries[i], "SYSLOG_IDENTIFIER"), "mfcd");
    EXPECT_EQ(field(entries[i], "SYSLOG_FACILITY"), "3");
    EXPECT_EQ(field(entries[i], "MFCD_CYCLE"), std::to_string(cycle + i));
    EXPECT_EQ(field(entries[i], "MFCD_JOB_ID"), std::to_string(job));
  }
  EXPECT_EQ(field(entries[0], "MESSAGE"), flattened(error_line(cycle, static_cast<std::uint16_t>(job))));
  EXPECT_EQ(field(entries[0], "PRIORITY"), "3");
  EXPECT_EQ(field(entries[0], "MFCD_ERROR_CODE"), "2");
  EXPECT_EQ(field(entries[0], "MFCD_PART"), "-");
  EXPECT_EQ(field(entries[1], "MESSAGE"), pick_line(cycle + 1, static_cast<std::uint16_t>(job)));
  EXPECT_EQ(field(entries[1], "PRIORITY"), "6");
  EXPECT_EQ(field(entries[1], "MFCD_ERROR_CODE"), "0");
  EXPECT_EQ(field(entries[1], "MFCD_PART"), "4");
  EXPECT_EQ(field(entries[1], "MFCD_SCORE"), "0.625");
  EXPECT_EQ(field(entries[2], "MESSAGE"), no_pick_line(cycle + 2, static_cast<std::uint16_t>(job)));
  EXPECT_EQ(field(entries[2], "PRIORITY"), "5");
  EXPECT_EQ(field(entries[2], "MFCD_ERROR_CODE"), "0");
  EXPECT_EQ(field(entries[2], "MFCD_SCORE"), "-");

  // journalctl MFCD_ERROR_CODE=2: the error line only.
  const auto& errors = sections["error-code-2"];
  ASSERT_EQ(errors.size(), 1u) << out;
  EXPECT_EQ(field(errors[0], "MFCD_CYCLE"), std::to_string(cycle));

  // The probe's stdout/stderr stream: the sink found the journal, and no cycle line went there too.
  bool open = false;
  for (const auto& e : sections["stdout"]) {
    const std::string m = field(e, "MESSAGE");
    if (m == "probe job " + std::to_string(job) + ": journal sink open") open = true;
    EXPECT_EQ(m.find("cycle "), std::string::npos) << "a cycle line on the stderr stream as well: " << m;
  }
  EXPECT_TRUE(open) << out;
}
