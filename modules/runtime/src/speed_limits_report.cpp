#include "mosaicloc/runtime/speed_limits_report.hpp"

#include <fmt/printf.h>

namespace mosaicloc::runtime {

SpeedLimitsReport AnalyseSpeedLimits(const std::filesystem::path& config, std::optional<double> speed_mps) {
  SpeedLimitsReport report;
  if (!config.empty()) report.options = localizer::LoadSpeedLimitConfig(config);
  if (speed_mps) report.options.speed_mps = *speed_mps;
  report.limits = localizer::AnalyseSpeedLimits(report.options);
  return report;
}

nlohmann::json SpeedLimitsReport::ToJson() const {
  const localizer::SpeedLimitOptions& o = options;
  const localizer::SpeedLimits& l = limits;
  return {
      {"cycle_s", l.cycle_s},
      {"footprint_along_mm", l.footprint_along_mm},
      {"half_diagonal_px", l.half_diagonal_px},
      {"overlap_speed_limit_mps", l.overlap_limit_mps},
      {"distortion_speed_limit_mps", l.distortion_limit_mps},
      {"blur_speed_limit_mps", l.blur_limit_mps},
      {"prediction_speed_limit_mps", l.prediction_limit_mps},
      {"mosaic_speed_limit_mps", l.mosaic_limit_mps},
      {"height_tolerance_mm", l.height_tolerance_mm},
      {"scaled_height_tolerance_mm", l.scaled_height_tolerance_mm},
      {"rigid_tilt_tolerance_deg", l.rigid_tilt_tolerance_deg},
      {"tilt_tolerance_deg", l.tilt_tolerance_deg},
      {"tilt_lever_mm_per_deg", l.tilt_lever_mm_per_deg},
      {"relief_scale", l.relief_scale},
      {"relief_parallax_px", l.relief_parallax_px},
      {"relief_parallax_mm", l.relief_parallax_mm},
      {"relief_shadow_mm", l.relief_shadow_mm},
      {"relief_distortion_speed_limit_mps", l.relief_distortion_limit_mps},
      {"mapping_scale_error", l.mapping_scale_error},
      {"mapping_drift_mm", l.mapping_drift_mm},
      {"speed_mps", o.speed_mps},
      {"step_mm", l.step_mm},
      {"instability_ratio", l.instability_ratio},
      {"blur_px", l.blur_px},
      {"prediction_error_mm", l.prediction_error_mm},
      {"frame_to_frame_holds", l.frame_to_frame_holds},
      {"mosaic_holds", l.mosaic_holds}};
}

std::string SpeedLimitsReport::Text() const {
  const localizer::SpeedLimitOptions& o = options;
  const localizer::SpeedLimits& l = limits;
  std::string out;
  out += fmt::sprintf("setup: %dx%d px at %.4g mm/px, %.4g Hz (T_cyc %.2f ms), exposure %.4g us, camera %.4g mm above the floor\n",
                      o.width_px, o.height_px, o.mm_per_px, o.frame_rate_hz, 1e3 * l.cycle_s, o.exposure_us,
                      o.camera_height_mm);
  out += fmt::sprintf("footprint along the travel: Lambda = %.1f mm; image half-diagonal R = %.1f px\n\n",
                      l.footprint_along_mm, l.half_diagonal_px);
  out += fmt::sprintf("frame-to-frame registration (visual odometry, mapping by chaining frames):\n");
  out += fmt::sprintf("  overlap speed limit     V < (Lambda / T_cyc)(1 - beta)  = %7.2f m/s   (beta = %.2f)\n",
                      l.overlap_limit_mps, o.required_overlap);
  out += fmt::sprintf("  distortion speed limit  V < e h / (R g T_cyc)          = %7.2f m/s   (g = %.4g mm/mm, e = %.2f px)\n",
                      l.distortion_limit_mps, o.depth_gradient, o.distortion_tolerance_px);
  out += fmt::sprintf("tracking against the mosaic:\n");
  out += fmt::sprintf("  motion-blur limit       V < b s / T_exp                = %7.2f m/s   (b = %.2f px)\n",
                      l.blur_limit_mps, o.max_blur_px);
  out += fmt::sprintf("  prediction limit        V < r s / (epsilon T_cyc)      = %7.2f m/s   (r = %.0f px, epsilon = %.3g)\n",
                      l.prediction_limit_mps, o.search_range_px, o.odometry_error);
  out += fmt::sprintf("  height tolerance        |dh| < e h / R                 = %7.3f mm    (floor against the mapped height, rigid fit)\n",
                      l.height_tolerance_mm);
  out += fmt::sprintf("    with the scale estimated  |dh| < k h                  = %7.1f mm    (k = %.3g, known to work at a first fix)\n",
                      l.scaled_height_tolerance_mm, o.max_scale_error);
  out += fmt::sprintf("  tilt tolerance          |a| < e h / (s R^2)            = %7.3f deg   (keystone at the corner, fit without the tilt)\n",
                      l.rigid_tilt_tolerance_deg);
  out += fmt::sprintf("    with the tilt estimated   |a| < a_max                 = %7.2f deg   (known to work, twelve templates)\n",
                      l.tilt_tolerance_deg);
  out += fmt::sprintf("  tilt lever              p a                            = %7.3f mm per deg (pivot p = %.4g mm; out of the fix only with the tilt estimated)\n",
                      l.tilt_lever_mm_per_deg, o.tilt_pivot_height_mm);
  out += fmt::sprintf("  mosaic speed limit      min(blur, prediction)          = %7.2f m/s   (%.1f x the overlap speed limit)\n",
                      l.mosaic_limit_mps, l.mosaic_limit_mps / l.overlap_limit_mps);
  if (o.relief_depth_mm > 0.0) {
    out += fmt::sprintf("relief (joints d = %.3g mm below the tops, ring light rho = %.4g mm):\n", o.relief_depth_mm,
                        o.light_ring_radius_mm);
    out += fmt::sprintf("  image speed of the joints against the tops  d / (h + d) = %7.3f %%\n", 100.0 * l.relief_scale);
    out += fmt::sprintf("  parallax at the image corner  R d / (h + d)            = %7.2f px    (%.3f mm: a template there can be biased by up to this)\n",
                        l.relief_parallax_px, l.relief_parallax_mm);
    out += fmt::sprintf("  shadow into a joint at the image centre  d rho / h     = %7.3f mm\n", l.relief_shadow_mm);
    out += fmt::sprintf("  relief distortion limit  V < e s (h + d) / (d T_cyc)   = %7.2f m/s   (frame-to-frame registration)\n",
                        l.relief_distortion_limit_mps);
  } else {
    out += fmt::sprintf("relief: none (floor.relief_depth_mm 0)\n");
  }
  out += fmt::sprintf("mapping by chaining frames (map build, automatic mapping):\n");
  out += fmt::sprintf("  scale error of a step   dh / h                          = %7.2g       (dh = %.3g mm: the camera's height wanders)\n",
                      l.mapping_scale_error, o.height_variation_mm);
  out += fmt::sprintf("  drift between loops     L dh / h                        = %7.3f mm    (L = %.3g m between loop closures)\n",
                      l.mapping_drift_mm, o.loop_spacing_m);
  out += fmt::sprintf("\n");
  const double visual_odometry_max = 1.0 - o.required_overlap;
  out += fmt::sprintf("at %.2f m/s: step S = %.1f mm per frame, instability ratio S / Lambda = %.3f (frame-to-frame needs < %.2f),\n",
                      o.speed_mps, l.step_mm, l.instability_ratio, visual_odometry_max);
  out += fmt::sprintf("  blur %.2f px, odometry drift between fixes %.2f mm against a search half-range of %.1f mm\n",
                      l.blur_px, l.prediction_error_mm, o.search_range_px * o.mm_per_px);
  const auto verdict = [](bool holds) { return holds ? "within its limits" : "beyond its limits"; };
  out += fmt::sprintf("  frame-to-frame registration: %s; mosaic tracking: %s\n", verdict(l.frame_to_frame_holds),
                      verdict(l.mosaic_holds));
  return out;
}

}  // namespace mosaicloc::runtime
