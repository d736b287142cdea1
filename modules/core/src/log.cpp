#include "mosaicloc/core/log.hpp"

#include <spdlog/sinks/stdout_color_sinks.h>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::core {

spdlog::logger& Log() {
  static const std::shared_ptr<spdlog::logger> logger = [] {
    auto created = std::make_shared<spdlog::logger>(
        "mosaicloc", std::make_shared<spdlog::sinks::stderr_color_sink_mt>());
    created->set_pattern("[%H:%M:%S.%e] [%^%l%$] %v");
    created->set_level(spdlog::level::info);
    return created;
  }();
  return *logger;
}

void SetLogLevel(LogLevel level) {
  switch (level) {
    case LogLevel::kDebug: Log().set_level(spdlog::level::debug); break;
    case LogLevel::kInfo: Log().set_level(spdlog::level::info); break;
    case LogLevel::kWarning: Log().set_level(spdlog::level::warn); break;
    case LogLevel::kError: Log().set_level(spdlog::level::err); break;
    case LogLevel::kOff: Log().set_level(spdlog::level::off); break;
  }
}

LogLevel ParseLogLevel(std::string_view name) {
  if (name == "debug") return LogLevel::kDebug;
  if (name == "info") return LogLevel::kInfo;
  if (name == "warning") return LogLevel::kWarning;
  if (name == "error") return LogLevel::kError;
  if (name == "off") return LogLevel::kOff;
  ThrowInvalidInput("unknown log level '" + std::string(name) +
                    "': use debug, info, warning, error or off");
}

}  // namespace mosaicloc::core
