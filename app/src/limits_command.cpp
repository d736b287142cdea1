// mosaicloc limits: the speed limits of a camera setup (the founding paper's section 2.2
// analysis), so an integrator can choose frame rate, exposure and field of view for a speed.
#include <cmath>
#include <cstdio>
#include <optional>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "report.hpp"
#include "mosaicloc/localizer/speed_limits.hpp"

namespace mosaicloc::app {
namespace {

void PrintLimits(const localizer::SpeedLimitOptions& o, const localizer::SpeedLimits& l) {
  std::printf("setup: %dx%d px at %.4g mm/px, %.4g Hz (T_cyc %.2f ms), exposure %.4g us, camera %.4g mm above the floor\n",
              o.width_px, o.height_px, o.mm_per_px, o.frame_rate_hz, 1e3 * l.cycle_s, o.exposure_us,
              o.camera_height_mm);
  std::printf("footprint along the travel: Lambda = %.1f mm; image half-diagonal R = %.1f px\n\n",
              l.footprint_along_mm, l.half_diagonal_px);
  std::printf("frame-to-frame registration (visual odometry, mapping by chaining frames):\n");
  std::printf("  overlap speed limit     V < (Lambda / T_cyc)(1 - beta)  = %7.2f m/s   (beta = %.2f)\n",
              l.overlap_limit_mps, o.required_overlap);
  std::printf("  distortion speed limit  V < e h / (R g T_cyc)          = %7.2f m/s   (g = %.4g mm/mm, e = %.2f px)\n",
              l.distortion_limit_mps, o.depth_gradient, o.distortion_tolerance_px);
  std::printf("tracking against the mosaic:\n");
  std::printf("  motion-blur limit       V < b s / T_exp                = %7.2f m/s   (b = %.2f px)\n",
              l.blur_limit_mps, o.max_blur_px);
  std::printf("  prediction limit        V < r s / (epsilon T_cyc)      = %7.2f m/s   (r = %.0f px, epsilon = %.3g)\n",
              l.prediction_limit_mps, o.search_range_px, o.odometry_error);
  std::printf("  height tolerance        |dh| < e h / R                 = %7.3f mm    (floor against the mapped height, rigid fit)\n",
              l.height_tolerance_mm);
  std::printf("    with the scale estimated  |dh| < k h                  = %7.1f mm    (k = %.3g, known to work at a first fix)\n",
              l.scaled_height_tolerance_mm, o.max_scale_error);
  std::printf("  tilt tolerance          |a| < e h / (s R^2)            = %7.3f deg   (keystone at the corner, fit without the tilt)\n",
              l.rigid_tilt_tolerance_deg);
  std::printf("    with the tilt estimated   |a| < a_max                 = %7.2f deg   (known to work, twelve templates)\n",
              l.tilt_tolerance_deg);
  std::printf("  tilt lever              p a                            = %7.3f mm per deg (pivot p = %.4g mm; out of the fix only with the tilt estimated)\n",
              l.tilt_lever_mm_per_deg, o.tilt_pivot_height_mm);
  std::printf("  mosaic speed limit      min(blur, prediction)          = %7.2f m/s   (%.1f x the overlap speed limit)\n",
              l.mosaic_limit_mps, l.mosaic_limit_mps / l.overlap_limit_mps);
  if (o.relief_depth_mm > 0.0) {
    std::printf("relief (joints d = %.3g mm below the tops, ring light rho = %.4g mm):\n", o.relief_depth_mm,
                o.light_ring_radius_mm);
    std::printf("  image speed of the joints against the tops  d / (h + d) = %7.3f %%\n", 100.0 * l.relief_scale);
    std::printf("  parallax at the image corner  R d / (h + d)            = %7.2f px    (%.3f mm: a template there can be biased by up to this)\n",
                l.relief_parallax_px, l.relief_parallax_mm);
    std::printf("  shadow into a joint at the image centre  d rho / h     = %7.3f mm\n", l.relief_shadow_mm);
    std::printf("  relief distortion limit  V < e s (h + d) / (d T_cyc)   = %7.2f m/s   (frame-to-frame registration)\n",
                l.relief_distortion_limit_mps);
  } else {
    std::printf("relief: none (floor.relief_depth_mm 0)\n");
  }
  std::printf("mapping by chaining frames (map build, automatic mapping):\n");
  std::printf("  scale error of a step   dh / h                          = %7.2g       (dh = %.3g mm: the camera's height wanders)\n",
              l.mapping_scale_error, o.height_variation_mm);
  std::printf("  drift between loops     L dh / h                        = %7.3f mm    (L = %.3g m between loop closures)\n",
              l.mapping_drift_mm, o.loop_spacing_m);
  std::printf("\n");
  const double visual_odometry_max = 1.0 - o.required_overlap;
  std::printf("at %.2f m/s: step S = %.1f mm per frame, instability ratio S / Lambda = %.3f (frame-to-frame needs < %.2f),\n",
              o.speed_mps, l.step_mm, l.instability_ratio, visual_odometry_max);
  std::printf("  blur %.2f px, odometry drift between fixes %.2f mm against a search half-range of %.1f mm\n",
              l.blur_px, l.prediction_error_mm, o.search_range_px * o.mm_per_px);
  const auto verdict = [](bool holds) { return holds ? "within its limits" : "beyond its limits"; };
  std::printf("  frame-to-frame registration: %s; mosaic tracking: %s\n", verdict(l.frame_to_frame_holds),
              verdict(l.mosaic_holds));
}

}  // namespace

Action AddLimitsCommand(CLI::App& app, const GlobalOptions& global) {
  struct Args {
    std::filesystem::path config;
    std::optional<double> speed_mps;
  };
  auto args = std::make_shared<Args>();
  CLI::App* command = app.add_subcommand(
      "limits", "Speed limits of a camera setup: overlap, distortion, blur, prediction, and the instability ratio");
  command->add_option("--config", args->config, "Setup YAML (see config/default/limits.yaml); defaults without it")
      ->check(CLI::ExistingFile);
  command->add_option("--speed-mps", args->speed_mps, "Speed for the per-frame figures, m/s (overrides speed_mps)")
      ->check(CLI::Range(0.0, 1000.0));
  return [args, &global] {
    localizer::SpeedLimitOptions options;
    if (!args->config.empty()) options = localizer::LoadSpeedLimitConfig(args->config);
    if (args->speed_mps) options.speed_mps = *args->speed_mps;
    const localizer::SpeedLimits limits = localizer::AnalyseSpeedLimits(options);
    if (!global.json) {
      PrintLimits(options, limits);
      return;
    }
    const nlohmann::json json = {
        {"cycle_s", limits.cycle_s},
        {"footprint_along_mm", limits.footprint_along_mm},
        {"half_diagonal_px", limits.half_diagonal_px},
        {"overlap_speed_limit_mps", limits.overlap_limit_mps},
        {"distortion_speed_limit_mps", limits.distortion_limit_mps},
        {"blur_speed_limit_mps", limits.blur_limit_mps},
        {"prediction_speed_limit_mps", limits.prediction_limit_mps},
        {"mosaic_speed_limit_mps", limits.mosaic_limit_mps},
        {"height_tolerance_mm", limits.height_tolerance_mm},
        {"scaled_height_tolerance_mm", limits.scaled_height_tolerance_mm},
        {"rigid_tilt_tolerance_deg", limits.rigid_tilt_tolerance_deg},
        {"tilt_tolerance_deg", limits.tilt_tolerance_deg},
        {"tilt_lever_mm_per_deg", limits.tilt_lever_mm_per_deg},
        {"relief_scale", limits.relief_scale},
        {"relief_parallax_px", limits.relief_parallax_px},
        {"relief_parallax_mm", limits.relief_parallax_mm},
        {"relief_shadow_mm", limits.relief_shadow_mm},
        {"relief_distortion_speed_limit_mps", limits.relief_distortion_limit_mps},
        {"mapping_scale_error", limits.mapping_scale_error},
        {"mapping_drift_mm", limits.mapping_drift_mm},
        {"speed_mps", options.speed_mps},
        {"step_mm", limits.step_mm},
        {"instability_ratio", limits.instability_ratio},
        {"blur_px", limits.blur_px},
        {"prediction_error_mm", limits.prediction_error_mm},
        {"frame_to_frame_holds", limits.frame_to_frame_holds},
        {"mosaic_holds", limits.mosaic_holds}};
    PrintJson(json);
  };
}

}  // namespace mosaicloc::app
