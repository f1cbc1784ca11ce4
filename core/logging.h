// The only logging facade of lisfm (STYLE.md): stage headers, progress and the
// end-of-command summary. Backed by spdlog, writing to stderr so that stdout
// stays clean for machine-readable output. Library code logs at debug/info;
// it never prints directly.
#pragma once

#include <string>

#include <fmt/format.h>

namespace lisfm {

enum class LogLevel { kDebug, kInfo, kWarning, kError, kOff };

void SetLogLevel(LogLevel level);
LogLevel GetLogLevel();

void LogMessage(LogLevel level, const std::string& message);

template <typename... Args>
void LogDebug(fmt::format_string<Args...> f, Args&&... args) {
  if (GetLogLevel() <= LogLevel::kDebug)
    LogMessage(LogLevel::kDebug, fmt::format(f, std::forward<Args>(args)...));
}
template <typename... Args>
void LogInfo(fmt::format_string<Args...> f, Args&&... args) {
  if (GetLogLevel() <= LogLevel::kInfo)
    LogMessage(LogLevel::kInfo, fmt::format(f, std::forward<Args>(args)...));
}
template <typename... Args>
void LogWarning(fmt::format_string<Args...> f, Args&&... args) {
  if (GetLogLevel() <= LogLevel::kWarning)
    LogMessage(LogLevel::kWarning, fmt::format(f, std::forward<Args>(args)...));
}
template <typename... Args>
void LogError(fmt::format_string<Args...> f, Args&&... args) {
  if (GetLogLevel() <= LogLevel::kError)
    LogMessage(LogLevel::kError, fmt::format(f, std::forward<Args>(args)...));
}

// Prints "== <title> ==" as a stage header.
void LogStage(const std::string& title);

// A one-line status kept on the last line of the terminal (the progress bar,
// core/progress.h), on stderr. ShowStatusLine draws or replaces it without a
// newline; a log message printed while it is shown first clears the line,
// then prints, then draws the status again, so messages never land inside the
// bar. EndStatusLine draws it a last time, ends the line and forgets it.
// `text` holds no newline. Thread-safe (one lock for all stderr output here).
void ShowStatusLine(const std::string& text);
void EndStatusLine(const std::string& text);

}  // namespace lisfm
