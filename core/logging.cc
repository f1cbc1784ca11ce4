#include "core/logging.h"

#include <atomic>
#include <cstdio>
#include <memory>
#include <mutex>

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

namespace lisfm {
namespace {

std::atomic<LogLevel> g_level{LogLevel::kInfo};

// Guards stderr between log messages and the status line.
std::mutex g_terminal_mutex;
std::string g_status_line;  // shown on the terminal's last line; "" = none

// ANSI: carriage return, then erase the whole line.
constexpr const char* kClearLine = "\r\033[2K";

spdlog::logger& Logger() {
  static std::shared_ptr<spdlog::logger> logger = [] {
    auto l = spdlog::stderr_color_mt("lisfm");
    l->set_pattern("%^[%L %H:%M:%S.%e]%$ %v");
    l->set_level(spdlog::level::trace);
    return l;
  }();
  return *logger;
}

}  // namespace

void SetLogLevel(LogLevel level) { g_level = level; }
LogLevel GetLogLevel() { return g_level; }

void LogMessage(LogLevel level, const std::string& message) {
  std::lock_guard<std::mutex> lock(g_terminal_mutex);
  if (!g_status_line.empty()) std::fputs(kClearLine, stderr);
  switch (level) {
    case LogLevel::kDebug:
      Logger().debug(message);
      break;
    case LogLevel::kInfo:
      Logger().info(message);
      break;
    case LogLevel::kWarning:
      Logger().warn(message);
      break;
    case LogLevel::kError:
      Logger().error(message);
      break;
    case LogLevel::kOff:
      break;
  }
  Logger().flush();
  if (!g_status_line.empty()) {
    std::fputs(g_status_line.c_str(), stderr);
    std::fflush(stderr);
  }
}

void LogStage(const std::string& title) {
  if (GetLogLevel() <= LogLevel::kInfo) LogMessage(LogLevel::kInfo, "== " + title + " ==");
}

void ShowStatusLine(const std::string& text) {
  std::lock_guard<std::mutex> lock(g_terminal_mutex);
  g_status_line = text;
  std::fputs(kClearLine, stderr);
  std::fputs(text.c_str(), stderr);
  std::fflush(stderr);
}

void EndStatusLine(const std::string& text) {
  std::lock_guard<std::mutex> lock(g_terminal_mutex);
  g_status_line.clear();
  std::fputs(kClearLine, stderr);
  std::fputs(text.c_str(), stderr);
  std::fputs("\n", stderr);
  std::fflush(stderr);
}

}  // namespace lisfm
