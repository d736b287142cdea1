#include "mosaicloc/runtime/report.hpp"

#include <algorithm>
#include <cmath>
#include <system_error>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/dataset/plots.hpp"

namespace mosaicloc::runtime {

dataset::Metrics WriteReport(const std::filesystem::path& directory, const dataset::Trajectory& estimate,
                             const std::optional<dataset::Trajectory>& groundtruth, dataset::Metrics metrics,
                             const std::string& title) {
  std::error_code ec;
  std::filesystem::create_directories(directory, ec);
  if (ec) core::ThrowRuntime(directory.string() + ": cannot create the report directory (" + ec.message() + ")");
  dataset::WriteTum(directory / "estimate.tum", estimate);
  // No estimate at all (a start without a pose on a floor that repeats: never found): the
  // caller's counts are the report.
  if (groundtruth && !estimate.empty()) {
    const dataset::Evaluation evaluation = dataset::Evaluate(estimate, *groundtruth, dataset::EvaluationOptions{});
    // Keep what the caller measured; take the accuracy figures from the evaluation.
    dataset::Metrics merged = evaluation.metrics;
    const auto keep = [](auto& target, const auto& known) {
      if (known) target = known;
    };
    keep(merged.frames, metrics.frames);
    keep(merged.fixes, metrics.fixes);
    keep(merged.fix_rate, metrics.fix_rate);
    keep(merged.lock_losses, metrics.lock_losses);
    keep(merged.wrong_fixes, metrics.wrong_fixes);
    keep(merged.max_wrong_fix_mm, metrics.max_wrong_fix_mm);
    keep(merged.fix_error_rms_mm, metrics.fix_error_rms_mm);
    keep(merged.off_map_frames, metrics.off_map_frames);
    keep(merged.off_map_max_error_mm, metrics.off_map_max_error_mm);
    keep(merged.skipped_frames, metrics.skipped_frames);
    keep(merged.skipped_encoder_samples, metrics.skipped_encoder_samples);
    keep(merged.reentries, metrics.reentries);
    keep(merged.reentry_frames_to_fix_max, metrics.reentry_frames_to_fix_max);
    keep(merged.reentry_first_fix_error_max_mm, metrics.reentry_first_fix_error_max_mm);
    keep(merged.relocalizations, metrics.relocalizations);
    keep(merged.wheel_scale_left_percent, metrics.wheel_scale_left_percent);
    keep(merged.wheel_scale_right_percent, metrics.wheel_scale_right_percent);
    keep(merged.drive_wheel_scale_percent, metrics.drive_wheel_scale_percent);
    keep(merged.steering_offset_error_deg, metrics.steering_offset_error_deg);
    keep(merged.frames_to_first_fix, metrics.frames_to_first_fix);
    keep(merged.first_fix_s, metrics.first_fix_s);
    keep(merged.kidnap_frames_to_fix, metrics.kidnap_frames_to_fix);
    keep(merged.map_extension_segments, metrics.map_extension_segments);
    keep(merged.map_extension_closed, metrics.map_extension_closed);
    keep(merged.map_extension_keyframes, metrics.map_extension_keyframes);
    keep(merged.map_extension_tiles, metrics.map_extension_tiles);
    keep(merged.map_extension_unanchored, metrics.map_extension_unanchored);
    keep(merged.map_extension_closure_max_mm, metrics.map_extension_closure_max_mm);
    keep(merged.map_extension_pose_rms_mm, metrics.map_extension_pose_rms_mm);
    keep(merged.map_extension_pose_max_mm, metrics.map_extension_pose_max_mm);
    keep(merged.map_extension_overspeed_frames, metrics.map_extension_overspeed_frames);
    keep(merged.map_extension_speed_max_mps, metrics.map_extension_speed_max_mps);
    keep(merged.map_update, metrics.map_update);
    keep(merged.processing_fps, metrics.processing_fps);
    keep(merged.latency_p50_ms, metrics.latency_p50_ms);
    keep(merged.latency_p99_ms, metrics.latency_p99_ms);
    keep(merged.overlap_speed_limit_mps, metrics.overlap_speed_limit_mps);
    keep(merged.height_error_rms_mm, metrics.height_error_rms_mm);
    keep(merged.height_error_max_mm, metrics.height_error_max_mm);
    // The figures that need no truth are the caller's.
    merged.estimate_path_length_m = metrics.estimate_path_length_m;
    merged.estimate_speed_mean_mps = metrics.estimate_speed_mean_mps;
    merged.estimate_speed_p99_mps = metrics.estimate_speed_p99_mps;
    merged.frames_by_state = metrics.frames_by_state;
    merged.fixes_by_state = metrics.fixes_by_state;
    merged.no_fix_reasons = metrics.no_fix_reasons;
    merged.frames_by_mode = metrics.frames_by_mode;
    merged.mode_switches = metrics.mode_switches;
    merged.nis_fixes = metrics.nis_fixes;
    merged.nis_inside_95_share = metrics.nis_inside_95_share;
    merged.nis_mean = metrics.nis_mean;
    merged.innovation_sigma_ratio = metrics.innovation_sigma_ratio;
    merged.repeatability_camera_mm = metrics.repeatability_camera_mm;
    merged.repeatability_camera_places = metrics.repeatability_camera_places;
    merged.revisit_repeatability_mm = metrics.revisit_repeatability_mm;
    merged.revisit_places = metrics.revisit_places;
    merged.revisit_visits = metrics.revisit_visits;
    merged.revisit_failures = metrics.revisit_failures;
    metrics = merged;
    dataset::WritePlots(directory, evaluation, title);
  }
  dataset::WriteMetricsJson(directory / "metrics.json", metrics);
  return metrics;
}

dataset::FloorPicture FloorPictureOf(const MapSession& map, const std::vector<dataset::FrameReport>& reports) {
  dataset::FloorPicture picture;
  if (reports.empty()) return picture;
  Eigen::Vector2d lo = reports.front().world_from_vehicle.translation_mm(), hi = lo;
  for (const dataset::FrameReport& r : reports) {
    lo = lo.cwiseMin(r.world_from_vehicle.translation_mm());
    hi = hi.cwiseMax(r.world_from_vehicle.translation_mm());
  }
  const double margin_mm = std::max(500.0, 0.25 * (hi - lo).maxCoeff());
  lo.array() -= margin_mm;
  hi.array() += margin_mm;
  constexpr double kLargestPx = 1600.0, kTooLargePx = 6000.0;
  const mosaic::MapGrid& grid = map.grid();
  int level = 0;
  while (level + 1 < grid.levels && (hi - lo).maxCoeff() / grid.LevelMmPerPx(level) > kLargestPx) ++level;
  const double mm_per_px = grid.LevelMmPerPx(level);
  if ((hi - lo).maxCoeff() / mm_per_px > kTooLargePx) return picture;
  const Eigen::Vector2d top_left = grid.WorldToRaster({lo.x(), hi.y()}, level);
  const auto col0 = static_cast<std::int64_t>(std::floor(top_left.x()));
  const auto row0 = static_cast<std::int64_t>(std::floor(top_left.y()));
  const int cols = static_cast<int>(std::ceil((hi.x() - lo.x()) / mm_per_px)) + 2;
  const int rows = static_cast<int>(std::ceil((hi.y() - lo.y()) / mm_per_px)) + 2;
  const mosaic::RasterPatch patch = map.renderer().Region(level, col0, row0, cols, rows);
  picture.image = patch.image.clone();
  if (!patch.all_mapped) picture.image.setTo(255, patch.mask == 0);
  // Pixel (col, row)'s centre is raster (col, row): its outer edges are half a pixel out.
  const Eigen::Vector2d corner = grid.RasterToWorld({static_cast<double>(col0) - 0.5, static_cast<double>(row0) - 0.5}, level);
  picture.x0_mm = corner.x();
  picture.x1_mm = corner.x() + cols * mm_per_px;
  picture.y1_mm = corner.y();
  picture.y0_mm = corner.y() - rows * mm_per_px;
  return picture;
}

dataset::FrameReport FrameReportOf(core::Timestamp time, const localizer::FrameOutcome& outcome) {
  dataset::FrameReport report;
  report.time = time;
  report.fixed = outcome.fixed;
  report.world_from_vehicle = outcome.fixed ? outcome.fix_world_from_vehicle : outcome.world_from_vehicle;
  report.status = static_cast<int>(outcome.lock);
  report.quality = outcome.fixed ? outcome.fix_quality : 0.0;
  report.sigma_mm = std::sqrt(std::max(outcome.covariance(0, 0), outcome.covariance(1, 1)));
  report.scale = outcome.scale;
  report.nis = outcome.nis;
  report.reason = outcome.ReasonWord();
  report.mode = localizer::ToString(outcome.mode);
  return report;
}

}  // namespace mosaicloc::runtime
