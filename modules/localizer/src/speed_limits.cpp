#include "mosaicloc/localizer/speed_limits.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/yaml.hpp"

namespace mosaicloc::localizer {

bool SpeedLimitOptions::Check(std::string* why) const {
  auto fail = [why](const char* message) {
    if (why != nullptr) *why = message;
    return false;
  };
  const camera::IdealCameraOptions camera{width_px, height_px, mm_per_px};
  if (!camera.Check(why)) return false;
  if (!(frame_rate_hz > 0.0)) return fail("frame_rate_hz must be > 0");
  if (!(exposure_us > 0.0)) return fail("exposure_us must be > 0");
  if (!(camera_height_mm > 0.0)) return fail("camera_height_mm must be > 0");
  if (!std::isfinite(travel_direction_rad)) return fail("travel_direction_rad must be finite");
  if (!(depth_gradient > 0.0)) return fail("depth_gradient must be > 0");
  if (!(relief_depth_mm >= 0.0 && relief_depth_mm <= 100.0)) return fail("relief_depth_mm must be in [0, 100]");
  if (!(height_variation_mm >= 0.0 && height_variation_mm <= 100.0)) return fail("height_variation_mm must be in [0, 100]");
  if (!(loop_spacing_m > 0.0 && loop_spacing_m <= 100000.0)) return fail("loop_spacing_m must be in (0, 100000]");
  if (!(light_ring_radius_mm >= 0.0 && light_ring_radius_mm <= 1000.0)) {
    return fail("light_ring_radius_mm must be in [0, 1000]");
  }
  if (!(required_overlap >= 0.0 && required_overlap < 1.0)) return fail("required_overlap must be in [0, 1)");
  if (!(distortion_tolerance_px > 0.0)) return fail("distortion_tolerance_px must be > 0");
  if (!(max_blur_px > 0.0)) return fail("max_blur_px must be > 0");
  if (!(search_range_px > 0.0)) return fail("search_range_px must be > 0");
  if (!(odometry_error > 0.0 && odometry_error < 1.0)) return fail("odometry_error must be in (0, 1)");
  if (!(tilt_pivot_height_mm >= -1000.0 && tilt_pivot_height_mm <= 2000.0)) {
    return fail("tilt_pivot_height_mm must be in [-1000, 2000]");
  }
  if (!(max_scale_error > 0.0 && max_scale_error < 1.0)) return fail("max_scale_error must be in (0, 1)");
  if (!(max_tilt_deg > 0.0 && max_tilt_deg < 45.0)) return fail("max_tilt_deg must be in (0, 45)");
  if (!(speed_mps >= 0.0 && std::isfinite(speed_mps))) return fail("speed_mps must be >= 0");
  return true;
}

OverlapSpeedWatch::OverlapSpeedWatch(const camera::IdealCamera& camera, double required_overlap)
    : camera_(camera), required_overlap_(required_overlap) {
  if (!(required_overlap >= 0.0 && required_overlap < 1.0)) {
    core::ThrowInvalidInput("overlap speed watch: required_overlap must be in [0, 1)");
  }
}

std::optional<OverlapSpeedWatch::Excess> OverlapSpeedWatch::Frame(core::Timestamp time,
                                                                 const core::Pose2& world_from_camera, bool mapping) {
  std::optional<Excess> excess;
  if (last_time_ && time > *last_time_ && mapping) {
    const double dt_s = core::ToSeconds(time - *last_time_);
    // The step in the camera frame at the earlier frame: its direction there is what the
    // footprint is measured along.
    const Eigen::Vector2d step = (last_pose_.Inverse() * world_from_camera).translation_mm();
    const double step_mm = step.norm();
    const double speed_mps = 1e-3 * step_mm / dt_s;
    max_speed_mps_ = std::max(max_speed_mps_, speed_mps);
    const double allowed_mm =
        camera_.FootprintLengthAlong(std::atan2(step.y(), step.x())) * (1.0 - required_overlap_);
    if (step_mm > allowed_mm) {
      ++frames_over_;
      const bool first = !last_over_ || core::ToSeconds(time - *last_over_) >= kQuietS;
      last_over_ = time;
      excess = Excess{speed_mps, 1e-3 * allowed_mm / dt_s, first};
    }
  }
  last_time_ = time;
  last_pose_ = world_from_camera;
  return excess;
}

SpeedLimits AnalyseSpeedLimits(const SpeedLimitOptions& options) {
  std::string why;
  if (!options.Check(&why)) core::ThrowInvalidInput("speed limits: " + why);
  const camera::IdealCamera camera({options.width_px, options.height_px, options.mm_per_px});
  SpeedLimits limits;
  const double s = options.mm_per_px;
  const double cycle_s = 1.0 / options.frame_rate_hz;
  const double exposure_s = options.exposure_us * 1e-6;
  limits.cycle_s = cycle_s;
  limits.footprint_along_mm = camera.FootprintLengthAlong(options.travel_direction_rad);
  limits.half_diagonal_px = 0.5 * std::hypot(options.width_px, options.height_px);
  // mm/s to m/s below: every limit is a length in mm over a time in s.
  limits.overlap_limit_mps = 1e-3 * limits.footprint_along_mm * (1.0 - options.required_overlap) / cycle_s;
  limits.height_tolerance_mm = options.distortion_tolerance_px * options.camera_height_mm / limits.half_diagonal_px;
  limits.distortion_limit_mps = 1e-3 * limits.height_tolerance_mm / (options.depth_gradient * cycle_s);
  limits.scaled_height_tolerance_mm = options.max_scale_error * options.camera_height_mm;
  const double degree = std::numbers::pi / 180.0;
  limits.rigid_tilt_tolerance_deg = options.distortion_tolerance_px * options.camera_height_mm /
                                    (s * limits.half_diagonal_px * limits.half_diagonal_px) / degree;
  limits.tilt_tolerance_deg = options.max_tilt_deg;
  limits.tilt_lever_mm_per_deg = options.tilt_pivot_height_mm * degree;
  limits.blur_limit_mps = 1e-3 * options.max_blur_px * s / exposure_s;
  limits.prediction_limit_mps = 1e-3 * options.search_range_px * s / (options.odometry_error * cycle_s);
  limits.mosaic_limit_mps = std::min(limits.blur_limit_mps, limits.prediction_limit_mps);
  const double d = options.relief_depth_mm;
  const double h = options.camera_height_mm;
  if (d > 0.0) {
    limits.relief_scale = d / (h + d);
    limits.relief_parallax_px = limits.half_diagonal_px * limits.relief_scale;
    limits.relief_parallax_mm = limits.relief_parallax_px * s;
    limits.relief_shadow_mm = d * options.light_ring_radius_mm / h;
    limits.relief_distortion_limit_mps = 1e-3 * options.distortion_tolerance_px * s * (h + d) / (d * cycle_s);
  }

  limits.mapping_scale_error = options.height_variation_mm / h;
  limits.mapping_drift_mm = 1e3 * options.loop_spacing_m * limits.mapping_scale_error;

  limits.step_mm = 1e3 * options.speed_mps * cycle_s;
  limits.instability_ratio = limits.step_mm / limits.footprint_along_mm;
  limits.blur_px = 1e3 * options.speed_mps * exposure_s / s;
  limits.prediction_error_mm = options.odometry_error * limits.step_mm;
  limits.frame_to_frame_holds =
      limits.instability_ratio < 1.0 - options.required_overlap && options.speed_mps < limits.distortion_limit_mps;
  limits.mosaic_holds = options.speed_mps < limits.mosaic_limit_mps;
  return limits;
}

SpeedLimitOptions LoadSpeedLimitConfig(const std::filesystem::path& file) {
  SpeedLimitOptions o;
  core::YamlProblems problems;
  core::YamlMap root = core::YamlMap::Root(core::LoadYamlFile(file), file.string(), &problems);
  core::YamlMap camera = root.OptionalMap("camera");
  camera.Optional("width_px", &o.width_px);
  camera.Optional("height_px", &o.height_px);
  camera.Optional("mm_per_px", &o.mm_per_px);
  camera.Optional("frame_rate_hz", &o.frame_rate_hz);
  camera.Optional("exposure_us", &o.exposure_us);
  camera.Optional("height_mm", &o.camera_height_mm);
  camera.Optional("tilt_pivot_height_mm", &o.tilt_pivot_height_mm);
  camera.Optional("light_ring_radius_mm", &o.light_ring_radius_mm);
  double yaw_rad = -o.travel_direction_rad;
  camera.Optional("vehicle_from_camera_yaw_rad", &yaw_rad);
  o.travel_direction_rad = -yaw_rad;
  camera.CheckOwnKeys(o, {{"camera_height_mm", "height_mm"}, {"travel_direction_rad", "vehicle_from_camera_yaw_rad"}});
  camera.Finish();
  core::YamlMap floor = root.OptionalMap("floor");
  floor.Optional("depth_gradient", &o.depth_gradient);
  floor.Optional("relief_depth_mm", &o.relief_depth_mm);
  floor.Optional("height_variation_mm", &o.height_variation_mm);
  floor.Optional("loop_spacing_m", &o.loop_spacing_m);
  floor.CheckOwnKeys(o);
  floor.Finish();
  core::YamlMap tracker = root.OptionalMap("tracker");
  tracker.Optional("required_overlap", &o.required_overlap);
  tracker.Optional("distortion_tolerance_px", &o.distortion_tolerance_px);
  tracker.Optional("max_blur_px", &o.max_blur_px);
  tracker.Optional("search_range_px", &o.search_range_px);
  tracker.Optional("odometry_error", &o.odometry_error);
  tracker.Optional("max_scale_error", &o.max_scale_error);
  tracker.Optional("max_tilt_deg", &o.max_tilt_deg);
  tracker.CheckOwnKeys(o);
  tracker.Finish();
  root.Optional("speed_mps", &o.speed_mps);
  root.Finish();
  if (problems.empty()) root.Check(o);
  problems.ThrowIfAny();
  return o;
}

}  // namespace mosaicloc::localizer
