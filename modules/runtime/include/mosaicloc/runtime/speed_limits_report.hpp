#pragma once

#include <filesystem>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "mosaicloc/localizer/speed_limits.hpp"

namespace mosaicloc::runtime {

/// `mosaicloc limits`: the speed limits of a camera setup (localizer::AnalyseSpeedLimits) and
/// the setup they were worked out for.
struct SpeedLimitsReport {
  localizer::SpeedLimitOptions options;
  localizer::SpeedLimits limits;

  /// `limits --json`: every limit and tolerance, and the per-frame figures at options' speed.
  nlohmann::json ToJson() const;
  /// What `limits` prints: the setup, each limit with its formula and terms, the relief and
  /// mapping terms, and the verdict at options' speed.
  std::string Text() const;
};

/// The setup from `config` (localizer::LoadSpeedLimitConfig; the defaults when empty), its
/// speed replaced by `speed_mps` when given, and its limits.
SpeedLimitsReport AnalyseSpeedLimits(const std::filesystem::path& config, std::optional<double> speed_mps);

}  // namespace mosaicloc::runtime
