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
    keep(merged.reentries, metrics.reentries);
    keep(merged.reentry_frames_to_fix_max, metrics.reentry_frames_to_fix_max);
    keep(merged.reentry_first_fix_error_max_mm, metrics.reentry_first_fix_error_max_mm);
    keep(merged.relocalizations, metrics.relocalizations);
    keep(merged.frames_to_first_fix, metrics.frames_to_first_fix);
    keep(merged.first_fix_s, metrics.first_fix_s);
    keep(merged.kidnap_frames_to_fix, metrics.kidnap_frames_to_fix);
    keep(merged.processing_fps, metrics.processing_fps);
    keep(merged.latency_p50_ms, metrics.latency_p50_ms);
    keep(merged.latency_p99_ms, metrics.latency_p99_ms);
    keep(merged.overlap_speed_limit_mps, metrics.overlap_speed_limit_mps);
    keep(merged.height_error_rms_mm, metrics.height_error_rms_mm);
    keep(merged.height_error_max_mm, metrics.height_error_max_mm);
    metrics = merged;
    dataset::WritePlots(directory, evaluation, title);
  }
  dataset::WriteMetricsJson(directory / "metrics.json", metrics);
  return metrics;
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
  report.reason = outcome.ReasonWord();
  return report;
}

}  // namespace mosaicloc::runtime
