#pragma once

#include <filesystem>
#include <optional>
#include <string>

#include <nlohmann/json_fwd.hpp>

#include "mosaicloc/dataset/evaluation.hpp"

namespace mosaicloc::app {

/// Prints a command's result as indented JSON (--json).
void PrintJson(const nlohmann::json& result);

/// Prints the headline figures, or the whole metrics as JSON.
void PrintMetrics(const std::filesystem::path& directory, const dataset::Metrics& metrics, bool json);

}  // namespace mosaicloc::app
