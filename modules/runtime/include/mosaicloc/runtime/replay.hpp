#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string_view>
#include <string>

#include <Eigen/Core>

#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/dataset/evaluation.hpp"
#include "mosaicloc/runtime/settings.hpp"

namespace mosaicloc::runtime {

enum class ReplayMode {
  kMosaic,          ///< localize against the map (the product)
  kDeadReckoning,   ///< wheel odometry alone, from the start pose
  kVisualOdometry,  ///< frame-to-frame registration chained without a map
};
inline constexpr ReplayMode kReplayModes[] = {ReplayMode::kMosaic, ReplayMode::kDeadReckoning,
                                              ReplayMode::kVisualOdometry};
/// "mosaic", "dead-reckoning", "visual-odometry": the names `replay --mode` takes.
const char* ToString(ReplayMode mode);
std::optional<ReplayMode> ParseReplayMode(std::string_view name);

struct ReplayOptions {
  std::filesystem::path dataset;
  std::filesystem::path map;  ///< kMosaic only
  std::filesystem::path out;  ///< the report directory
  ReplayMode mode = ReplayMode::kMosaic;
  LocalizationSettings settings;
  /// kMosaic: start this far from the true start, in the start's vehicle frame (a kidnapped
  /// vehicle; relocalization must find it).
  std::optional<core::Pose2> start_offset;
  /// A map built from a drive's own frames and encoders has a frame of its own, placed on the
  /// floor only as well as the first frames' poses were known: its pose in the truth's frame
  /// (a mapping report's truth_from_map). With it the ground truth is taken into the map's
  /// frame before the start is taken from it and anything is evaluated against it, so the
  /// figures (and the wrong fixes) are the localization's and not the map's placement.
  std::optional<core::Pose2> truth_from_map;
  /// kMosaic: the start is not to be trusted; relocalize without it.
  bool relocalize = false;
  /// kMosaic: the start is not known at all: search the whole map (Localizer::InitializeUnknown).
  bool unknown_start = false;
  /// kMosaic: a kidnapped vehicle. At the first frame `kidnap_at_s` seconds or more into the
  /// drive, the estimate is moved by `kidnap_offset` (in the vehicle's frame) and held there
  /// confidently (the start's uncertainty), as if the vehicle had been carried away from it
  /// unseen; with `kidnap_told` the localizer is also told (RequestRelocalization), as the
  /// PLC's relocalize request tells it.
  std::optional<double> kidnap_at_s;
  /// kMosaic: only the frames up to this many seconds into the drive are localized (the first
  /// stretch of a long recording); the report covers those.
  std::optional<double> until_s;
  core::Pose2 kidnap_offset;
  bool kidnap_told = false;
  /// kMosaic: load the map's tiles ahead on the prefetcher's threads, as a live run does;
  /// the estimates do not change, the processing times are the tracking thread's.
  bool prefetch = false;
  /// kMosaic: at most this many revisited places are registered frame to frame for the
  /// repeatability without ground truth (revisit_* in metrics.json); 0: none.
  std::int64_t revisit_places = 200;
  /// kMosaic: automatic mapping (design.md section 7d): the floor driven over off the map is
  /// added to it (settings.map_extension); the map is created empty when it does not exist.
  bool mapping = false;
  /// The configuration file `settings` came from, shown in index.html (empty: the built-in
  /// defaults).
  std::filesystem::path config_file;
};

/// What a replay did; the report directory holds the rest.
struct ReplaySummary {
  std::filesystem::path report;
  dataset::Metrics metrics;
  std::int64_t encoder_samples_rejected = 0;
  // kMosaic only:
  std::int64_t tiles_loaded = 0;
  std::int64_t relocalizations = 0;  ///< Localizer::relocalizations
  std::int64_t reanchorings = 0;     ///< Localizer::reanchorings
  Eigen::Vector2d wheel_scale_error = Eigen::Vector2d::Zero();  ///< learnt (left, right), 0.02 = 2 %
  Eigen::Vector2d wheel_scale_sigma = Eigen::Vector2d::Zero();
  /// With mapping: why map keeping stopped before the end (MapKeepingSummary::failure), or empty.
  std::string map_keeping_failure;
};

/// Replays a dataset in `options.mode` and writes the report (design.md section 4): a
/// deterministic run of what `run` does live, one thread, frames processed once the encoder
/// sample after them is in (each fix late, as on a vehicle). `progress` (may be empty) is
/// told the share of the dataset done, 0..1. Throws core::Error (invalid input) naming the
/// file or setting at fault.
ReplaySummary Replay(const ReplayOptions& options, const std::function<void(double)>& progress = {});

}  // namespace mosaicloc::runtime
