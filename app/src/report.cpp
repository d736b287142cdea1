#include "report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <optional>
#include <type_traits>

#include <nlohmann/json.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/dataset/plots.hpp"

namespace mosaicloc::app {

dataset::Metrics WriteReport(const std::filesystem::path& directory, const dataset::Trajectory& estimate,
                             const std::optional<dataset::Trajectory>& groundtruth, dataset::Metrics metrics,
                             const std::string& title) {
  std::error_code ec;
  std::filesystem::create_directories(directory, ec);
  if (ec) core::ThrowRuntime(directory.string() + ": cannot create the report directory (" + ec.message() + ")");
  dataset::WriteTum(directory / "estimate.tum", estimate);
  if (groundtruth) {
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
    keep(merged.off_map_frames, metrics.off_map_frames);
    keep(merged.off_map_max_error_mm, metrics.off_map_max_error_mm);
    keep(merged.reentries, metrics.reentries);
    keep(merged.reentry_frames_to_fix_max, metrics.reentry_frames_to_fix_max);
    keep(merged.reentry_first_fix_error_max_mm, metrics.reentry_first_fix_error_max_mm);
    keep(merged.relocalizations, metrics.relocalizations);
    keep(merged.processing_fps, metrics.processing_fps);
    keep(merged.latency_p50_ms, metrics.latency_p50_ms);
    keep(merged.latency_p99_ms, metrics.latency_p99_ms);
    keep(merged.overlap_speed_limit_mps, metrics.overlap_speed_limit_mps);
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
  report.reason = outcome.ReasonWord();
  return report;
}

void PrintMetrics(const std::filesystem::path& directory, const dataset::Metrics& metrics, bool json) {
  if (json) {
    std::ifstream in(directory / "metrics.json");
    const nlohmann::json parsed = nlohmann::json::parse(in);
    nlohmann::json result = {{"report", std::filesystem::absolute(directory).string()}, {"metrics", parsed}};
    std::printf("%s\n", result.dump(2).c_str());
    return;
  }
  const auto show = [](const char* name, const auto& value, const char* unit) {
    if (value && std::is_integral_v<std::decay_t<decltype(*value)>>) {
      std::printf("  %-24s %12lld %s\n", name, static_cast<long long>(*value), unit);
    } else if (value) {
      std::printf("  %-24s %12.4f %s\n", name, static_cast<double>(*value), unit);
    } else {
      std::printf("  %-24s %12s\n", name, "n/a");
    }
  };
  std::printf("report: %s\n", std::filesystem::absolute(directory).string().c_str());
  show("frames", metrics.frames, "");
  show("fixes", metrics.fixes, "");
  if (metrics.fix_rate) show("fix rate", std::optional<double>(100.0 * *metrics.fix_rate), "%");
  show("lock losses", metrics.lock_losses, "");
  show("wrong fixes (> 1 mm)", metrics.wrong_fixes, "");
  if (metrics.wrong_fixes && *metrics.wrong_fixes > 0) show("worst wrong fix", metrics.max_wrong_fix_mm, "mm");
  if (metrics.off_map_frames && *metrics.off_map_frames > 0) {
    show("off-map frames", metrics.off_map_frames, "");
    show("off-map dead reckoning", metrics.off_map_max_error_mm, "mm max");
  }
  if (metrics.reentries && *metrics.reentries > 0) {
    show("returns onto the map", metrics.reentries, "");
    show("  frames to first fix", metrics.reentry_frames_to_fix_max, "max");
    show("  first fix error", metrics.reentry_first_fix_error_max_mm, "mm max");
  }
  show("position RMS", metrics.position_rms_mm, "mm");
  show("position p99", metrics.position_p99_mm, "mm");
  show("position max", metrics.position_max_mm, "mm");
  show("heading RMS", metrics.heading_rms_deg, "deg");
  show("heading max", metrics.heading_max_deg, "deg");
  show("repeatability", metrics.repeatability_mm, "mm");
  show("final position error", metrics.final_position_error_mm, "mm");
  show("drift", metrics.drift_percent, "% of path");
  show("path length", metrics.path_length_m, "m");
  show("max speed", metrics.max_speed_mps, "m/s");
  show("overlap speed limit", metrics.overlap_speed_limit_mps, "m/s");
  show("processing", metrics.processing_fps, "frames/s");
  show("latency p50", metrics.latency_p50_ms, "ms");
  show("latency p99", metrics.latency_p99_ms, "ms");
}

}  // namespace mosaicloc::app
