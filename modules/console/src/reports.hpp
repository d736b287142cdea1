#pragma once

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

namespace mosaicloc::console::internal {

/// A report folder as the page draws it, read once at the console's start.
struct ReportLayer {
  std::string name;       ///< the folder's name
  std::string kind;       ///< "replay" or "mapping"
  nlohmann::json layer;   ///< what the page draws (see design.md section 5b)
};

/// Reads a replay report (fixes.csv, with metrics.json when present) or a mapping report
/// (consistency.json, path.csv, loops.csv). At most `max_points` points of a path are kept
/// (evenly thinned; every change of lock state or mode kept). Throws core::Error (invalid
/// input) naming the folder or file that is not a report or does not read.
ReportLayer ReadReportLayer(const std::filesystem::path& folder, std::size_t max_points = 20000);

}  // namespace mosaicloc::console::internal
