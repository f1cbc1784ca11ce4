#include "core/logging.h"

#include <atomic>
#include <memory>

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

namespace lisfm {
namespace {

std::atomic<LogLevel> g_level{LogLevel::kInfo};

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
}

void LogStage(const std::string& title) {
  if (GetLogLevel() <= LogLevel::kInfo) Logger().info("== {} ==", title);
}

}  // namespace lisfm
