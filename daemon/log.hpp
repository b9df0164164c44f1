#pragma once
// Plain syslog with levels; also to stderr when mfcd runs in the foreground. Never called on the
// frame path: the main thread logs a cycle's outcome after it has been published.
namespace mfcd::daemon {

enum class LogLevel { Error = 3, Warning = 4, Notice = 5, Info = 6, Debug = 7 };  // syslog values
const char* toString(LogLevel l);

void logOpen(const char* ident, bool toStderr, LogLevel level);
void logSetLevel(LogLevel level);
void logf(LogLevel level, const char* format, ...) __attribute__((format(printf, 2, 3)));

}  // namespace mfcd::daemon
