#include "mosaicloc/runtime/settings.hpp"

#include <cmath>
#include <numbers>
#include <string>

#include <fmt/format.h>

namespace mosaicloc::runtime {

bool LocalizationSettings::Check(std::string* why) const {
  if (!localizer.Check(why)) return false;
  const auto in = [why](const char* key, double value, double min, double max) {
    if (value >= min && value <= max) return true;
    *why = std::string(key) + " must be in [" + fmt::format("{:g}", min) + ", " + fmt::format("{:g}", max) + "]";
    return false;
  };
  return in("cache_budget_mib", static_cast<double>(cache_budget_mib), 16.0, 1 << 20) &&
         in("prefetch_horizon_s", prefetch_horizon_s, 0.0, 10.0) &&
         in("prefetch_turn_radius_mm", prefetch_turn_radius_mm, 0.0, 1e6) &&
         in("start_sigma_mm", start_sigma_mm, 1e-3, 1e5) && in("start_sigma_deg", start_sigma_deg, 1e-4, 180.0) &&
         in("required_overlap", required_overlap, 0.0, 0.95);
}

localizer::LocalizerOptions LocalizerOptionsFor(const localizer::LocalizerOptions& configured,
                                                const dataset::CameraInfo& camera, const dataset::VehicleInfo& vehicle,
                                                double encoder_timing_sigma_ms) {
  localizer::LocalizerOptions options = configured;
  options.odometry.wheels = vehicle;
  options.vehicle_from_camera = camera.vehicle_from_camera;
  options.odometry_timing_sigma_ms = encoder_timing_sigma_ms;
  return options;
}

mosaic::PrefetchOptions PrefetchOptionsFor(const LocalizationSettings& settings, const dataset::CameraInfo& camera) {
  mosaic::PrefetchOptions prefetch;
  prefetch.horizon_s = settings.prefetch_horizon_s;
  prefetch.view_radius_mm = 0.5 * std::hypot(camera.width_px, camera.height_px) * camera.mm_per_px + 30.0;
  prefetch.min_turn_radius_mm = settings.prefetch_turn_radius_mm;
  return prefetch;
}

void PredictTiles(mosaic::TilePrefetcher& prefetcher, const estimation::MotionState& motion,
                  const core::Pose2& vehicle_from_camera) {
  prefetcher.Predict(motion.world_from_vehicle * vehicle_from_camera,
                     motion.world_from_vehicle.Rotation() *
                         Eigen::Vector2d(motion.forward_speed_mm_per_s, motion.lateral_speed_mm_per_s),
                     motion.yaw_rate_rad_per_s);
}

Eigen::Matrix3d StartCovariance(double start_sigma_mm, double start_sigma_deg) {
  const double sigma_rad = start_sigma_deg * std::numbers::pi / 180.0;
  return Eigen::Vector3d(start_sigma_mm * start_sigma_mm, start_sigma_mm * start_sigma_mm, sigma_rad * sigma_rad)
      .asDiagonal();
}

CalibrationErrors CalibrationErrorsShown(const Eigen::Vector2d& states, core::DriveKind kind) {
  if (kind == core::DriveKind::kTricycle) {
    return {{"drive_wheel_scale_percent", "steering_offset_error_deg"},
            {100.0 * states.x(), states.y() * 180.0 / std::numbers::pi}};
  }
  if (kind == core::DriveKind::kMecanum) {
    return {{"wheel_scale_percent", "lateral_scale_percent"}, 100.0 * states};
  }
  return {{"wheel_scale_left_percent", "wheel_scale_right_percent"}, 100.0 * states};
}

}  // namespace mosaicloc::runtime
