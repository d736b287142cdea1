#pragma once

#include <cstddef>
#include <filesystem>
#include <string>

#include <yaml-cpp/yaml.h>

#include "mosaicloc/localizer/localizer.hpp"
#include "mosaicloc/mosaic/prefetcher.hpp"

namespace mosaicloc::app {

/// Everything `replay` (and later `run`) reads from --config: see config/default/localizer.yaml
/// for every key, its unit and default. Vehicle geometry and vehicle_from_camera come from
/// the dataset, not from here.
struct LocalizerConfig {
  localizer::LocalizerOptions localizer;
  std::size_t cache_budget_mib = 256;
  double prefetch_horizon_s = 1.0;  ///< how far ahead `run` loads the map's tiles (0: not at all)
  double prefetch_turn_radius_mm = 500.0;  ///< tightest turn whose branches `run` also loads (0: none)
  double start_sigma_mm = 1.0;     ///< uncertainty of the starting pose given to the filter
  double start_sigma_deg = 0.5;
  double required_overlap = 0.5;   ///< beta of the overlap speed limit
};

/// The prefetcher of `run` (and `replay --prefetch`): the configured horizon and turns, and
/// the camera's footprint (its half diagonal) with the tracker's search margin around it.
mosaic::PrefetchOptions PrefetchOptionsFor(const LocalizerConfig& config, int width_px, int height_px,
                                           double mm_per_px);

/// Asks `prefetcher` for the tiles along the path the motion state predicts for the camera.
void PredictTiles(mosaic::TilePrefetcher& prefetcher, const estimation::MotionState& motion,
                  const core::Pose2& vehicle_from_camera);

/// Reads a localizer configuration. Keys left out keep their defaults; unknown keys, wrong
/// types and values out of range are all reported at once as core::Error naming file, line
/// and key.
LocalizerConfig LoadLocalizerConfig(const std::filesystem::path& file);
void ReadLocalizerConfig(const YAML::Node& node, const std::string& file_name, LocalizerConfig* config);

}  // namespace mosaicloc::app
