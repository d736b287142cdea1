#pragma once

#include <filesystem>
#include <optional>
#include <string>

#include "mosaicloc/dataset/evaluation.hpp"

namespace mosaicloc::app {

/// Prints the headline figures, or the whole metrics as JSON.
void PrintMetrics(const std::filesystem::path& directory, const dataset::Metrics& metrics, bool json);

}  // namespace mosaicloc::app
