#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include "mosaicloc/console/console.hpp"

namespace mosaicloc::runtime {

/// `mosaicloc serve`: the console over a map and report folders, until a stop is asked for or
/// the duration passes.
struct ServeOptions {
  std::filesystem::path map;
  console::ConsoleOptions console;
  std::filesystem::path token_file;  ///< the token's file (console::ReadTokenFile), or empty
  double duration_s = 0.0;           ///< 0: until stopped
};

/// Starts the console, tells `started` its address, then polls `stop_requested` every 50 ms
/// (a reason to stop, or nothing). Returns the console's counters. Throws core::Error naming the
/// map, a report, the token file or the address on a bad start.
console::Console::Counters Serve(const ServeOptions& options, const std::function<void(const std::string& url)>& started,
                                 const std::function<std::optional<std::string>()>& stop_requested);

}  // namespace mosaicloc::runtime
