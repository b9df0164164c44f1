#pragma once
// What the harnesses share: a scratch directory for APIs that read files, and writing an input
// there. Each harness is one LLVMFuzzerTestOneInput (docs/fuzzing.md); it catches the exceptions
// its API documents, so anything else (a crash, a sanitizer report, another exception type, a
// timeout, an allocation over libFuzzer's -rss_limit_mb) is a finding.

#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>

namespace mfcd::fuzz {

// A directory private to this process, on /dev/shm when there is one (inputs are written
// there for every execution), removed at a normal exit. A crashed run leaves its directory
// behind; those of processes that no longer exist are removed when the next one starts.
inline const std::filesystem::path& scratch_dir() {
  // Never destroyed, so the exit handler below can still read it.
  static const std::filesystem::path* const dir = [] {
    std::error_code ec;
    std::filesystem::path base = "/dev/shm";
    if (!std::filesystem::is_directory(base, ec) || ::access(base.c_str(), W_OK) != 0)
      base = std::filesystem::temp_directory_path();
    const std::string prefix = "mfcd-fuzz-";
    for (const auto& e : std::filesystem::directory_iterator(base, ec)) {
      const std::string name = e.path().filename().string();
      if (name.rfind(prefix, 0) != 0) continue;
      const long pid = std::strtol(name.c_str() + prefix.size(), nullptr, 10);
      if (pid > 0 && ::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH)
        std::filesystem::remove_all(e.path(), ec);
    }
    auto* d = new std::filesystem::path(base / (prefix + std::to_string(::getpid())));
    std::filesystem::create_directories(*d);
    std::atexit([] {
      std::error_code ignored;
      std::filesystem::remove_all(scratch_dir(), ignored);
    });
    return d;
  }();
  return *dir;
}

inline void write_file(const std::filesystem::path& file, const uint8_t* data, size_t size) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  if (!out) {
    std::fprintf(stderr, "fuzz harness: cannot write %s\n", file.c_str());
    std::abort();
  }
}

inline void write_file(const std::filesystem::path& file, const std::string& text) {
  write_file(file, reinterpret_cast<const uint8_t*>(text.data()), text.size());
}

// A broken invariant of the code under test: reported like a crash.
[[noreturn]] inline void finding(const char* what) {
  std::fprintf(stderr, "fuzz harness: invariant broken: %s\n", what);
  std::abort();
}

}  // namespace mfcd::fuzz
