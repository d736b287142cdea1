#pragma once

#include <array>
#include <cstddef>

#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/estimation/pose_filter.hpp"
#include "mosaicloc/localizer/localizer.hpp"
#include "mosaicloc/mapping/map_extension.hpp"
#include "mosaicloc/mapping/map_update.hpp"
#include "mosaicloc/mosaic/prefetcher.hpp"

namespace mosaicloc::runtime {

/// What a localization job takes besides its inputs: the localizer's tuning and the map
/// cache (config/default/localizer.yaml gives every key, its unit and default). The vehicle's
/// geometry and vehicle_from_camera come from the dataset or the run's vehicle, never from
/// here (LocalizerOptionsFor).
struct LocalizationSettings {
  localizer::LocalizerOptions localizer;
  std::size_t cache_budget_mib = 256;
  double prefetch_horizon_s = 1.0;  ///< how far ahead the prefetcher loads the map's tiles (0: not at all)
  double prefetch_turn_radius_mm = 500.0;  ///< tightest turn whose branches are also loaded (0: none)
  double start_sigma_mm = 1.0;     ///< uncertainty of the starting pose given to the filter
  double start_sigma_deg = 0.5;
  double required_overlap = 0.5;   ///< beta of the overlap speed limit
  /// Automatic mapping (`replay --mapping`, design.md section 7d).
  mapping::MapExtensionOptions map_extension;
  /// Automatic map updates (`replay --mapping`, design.md section 7e).
  mapping::MapUpdateOptions map_update;
  /// The localizer's options and: cache_budget_mib in [16, 2^20], prefetch_horizon_s in
  /// [0, 10], prefetch_turn_radius_mm in [0, 1e6], start_sigma_mm in [1e-3, 1e5],
  /// start_sigma_deg in [1e-4, 180], required_overlap in [0, 0.95].
  bool Check(std::string* why) const;
};

/// The localizer options for one camera on one vehicle: the configured tuning and odometry
/// error model, the vehicle's wheel geometry, the camera's mounting, and the encoder time
/// stamps' uncertainty (0 for exact clocks).
localizer::LocalizerOptions LocalizerOptionsFor(const localizer::LocalizerOptions& configured,
                                                const dataset::CameraInfo& camera, const dataset::VehicleInfo& vehicle,
                                                double encoder_timing_sigma_ms);

/// The prefetcher's options: the configured horizon and turns, and the camera's footprint
/// (its half diagonal) with the tracker's search margin around it.
mosaic::PrefetchOptions PrefetchOptionsFor(const LocalizationSettings& settings, const dataset::CameraInfo& camera);

/// Asks `prefetcher` for the tiles along the path the motion state predicts for the camera.
void PredictTiles(mosaic::TilePrefetcher& prefetcher, const estimation::MotionState& motion,
                  const core::Pose2& vehicle_from_camera);

/// The filter's two calibration states (localizer::Localizer::wheel_scale_error) as a user
/// reads them, under the names metrics.json and a run's summary give them: a differential
/// drive's wheel scale errors in % (wheel_scale_left_percent, wheel_scale_right_percent), a
/// tricycle's drive wheel scale error in % and steering offset error in degrees
/// (drive_wheel_scale_percent, steering_offset_error_deg), a mecanum vehicle's wheel and
/// sideways scale errors in % (wheel_scale_percent, lateral_scale_percent).
struct CalibrationErrors {
  std::array<const char*, 2> names;
  Eigen::Vector2d values;
};
CalibrationErrors CalibrationErrorsShown(const Eigen::Vector2d& states, core::DriveKind kind);

/// The starting pose's covariance from the settings' start uncertainty.
Eigen::Matrix3d StartCovariance(double start_sigma_mm, double start_sigma_deg);

}  // namespace mosaicloc::runtime
