#pragma once

#include <memory>
#include <string_view>

#include <spdlog/spdlog.h>

namespace mosaicloc::core {

/// The library's logger ("mosaicloc"). It writes to standard error, never to standard
/// output: stdout belongs to the application (results, --json). The application may
/// replace the sinks or set the level; the library only logs.
spdlog::logger& Log();

enum class LogLevel { kDebug, kInfo, kWarning, kError, kOff };
void SetLogLevel(LogLevel level);
/// Parses "debug", "info", "warning", "error" or "off"; throws core::Error otherwise.
LogLevel ParseLogLevel(std::string_view name);

}  // namespace mosaicloc::core
