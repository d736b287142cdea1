#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mosaicloc/dataset/fixes.hpp"

namespace mosaicloc::runtime {

/// One figure of metrics.json in two reports; `difference` is b - a where both are numbers.
struct FigureComparison {
  std::string key;
  nlohmann::json a;
  nlohmann::json b;
  std::optional<double> difference;
};

/// A frame both reports hold (same time stamp) where their positions differ.
struct FrameDifference {
  dataset::FrameReport a;
  dataset::FrameReport b;
  double distance_mm = 0.0;
};

/// Two replays of the same recording side by side (design.md section 5, `report compare`).
struct ReportComparison {
  std::vector<FigureComparison> figures;  ///< every key of either metrics.json, a's order first
  std::int64_t common_frames = 0;         ///< frames in both fixes.csv files
  std::int64_t only_a = 0, only_b = 0;    ///< frames in one of them only
  std::int64_t fixed_only_a = 0;          ///< common frames with a fix in a, none in b
  std::int64_t fixed_only_b = 0;
  std::optional<double> position_difference_rms_mm;  ///< over the common frames
  std::vector<FrameDifference> largest;   ///< the common frames that differ most, largest first
};

/// Compares report directories `a` and `b` (each with metrics.json and fixes.csv); keeps the
/// `top` frames that differ most. Throws core::Error (invalid input) naming the file when one
/// is missing or malformed.
ReportComparison CompareReports(const std::filesystem::path& a, const std::filesystem::path& b, int top = 10);

}  // namespace mosaicloc::runtime
