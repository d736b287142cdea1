#include "mosaicloc/runtime/settings.hpp"

#include <cmath>
#include <numbers>

namespace mosaicloc::runtime {

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
  const double heading = motion.world_from_vehicle.yaw_rad();
  prefetcher.Predict(motion.world_from_vehicle * vehicle_from_camera,
                     motion.forward_speed_mm_per_s * Eigen::Vector2d(std::cos(heading), std::sin(heading)),
                     motion.yaw_rate_rad_per_s);
}

Eigen::Matrix3d StartCovariance(double start_sigma_mm, double start_sigma_deg) {
  const double sigma_rad = start_sigma_deg * std::numbers::pi / 180.0;
  return Eigen::Vector3d(start_sigma_mm * start_sigma_mm, start_sigma_mm * start_sigma_mm, sigma_rad * sigma_rad)
      .asDiagonal();
}

}  // namespace mosaicloc::runtime
