#include "report.hpp"

#include <cstdio>
#include <map>
#include <optional>
#include <string>
#include <type_traits>

#include <nlohmann/json.hpp>

namespace mosaicloc::app {

void PrintJson(const nlohmann::json& result) { std::printf("%s\n", result.dump(2).c_str()); }

void PrintMetrics(const std::filesystem::path& directory, const dataset::Metrics& metrics, bool json) {
  if (json) {
    nlohmann::json result = {{"report", std::filesystem::absolute(directory).string()},
                             {"metrics", nlohmann::json(dataset::MetricsJson(metrics))}};
    PrintJson(result);
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
  std::printf("report: %s (open index.html)\n", std::filesystem::absolute(directory).string().c_str());
  show("frames", metrics.frames, "");
  show("fixes", metrics.fixes, "");
  if (metrics.fix_rate) show("fix rate", std::optional<double>(100.0 * *metrics.fix_rate), "%");
  show("lock losses", metrics.lock_losses, "");
  show("wrong fixes (> 1 mm)", metrics.wrong_fixes, "");
  if (metrics.frames_to_first_fix && *metrics.frames_to_first_fix > 0) {
    show("frames to first fix", metrics.frames_to_first_fix, "");
    show("first fix after", metrics.first_fix_s, "s");
  }
  if (metrics.relocalizations && *metrics.relocalizations > 0) show("relocalizations", metrics.relocalizations, "");
  if (metrics.reanchorings && *metrics.reanchorings > 0) show("re-anchorings", metrics.reanchorings, "");
  if (metrics.wheel_scale_left_percent) {
    show("left wheel scale learnt", metrics.wheel_scale_left_percent, "%");
    show("right wheel scale learnt", metrics.wheel_scale_right_percent, "%");
  }
  if (metrics.drive_wheel_scale_percent) {
    show("drive wheel scale learnt", metrics.drive_wheel_scale_percent, "%");
    show("steering offset error learnt", metrics.steering_offset_error_deg, "deg");
  }
  if (metrics.wheel_scale_percent) {
    show("wheel scale learnt", metrics.wheel_scale_percent, "%");
    show("sideways scale learnt", metrics.lateral_scale_percent, "%");
  }
  if (metrics.kidnap_frames_to_fix) show("kidnap: frames to fix", metrics.kidnap_frames_to_fix, "");
  if (metrics.wrong_fixes && *metrics.wrong_fixes > 0) show("worst wrong fix", metrics.max_wrong_fix_mm, "mm");
  if (metrics.off_map_frames && *metrics.off_map_frames > 0) {
    show("off-map frames", metrics.off_map_frames, "");
    show("off-map dead reckoning", metrics.off_map_max_error_mm, "mm max");
  }
  if (metrics.skipped_frames.value_or(0) + metrics.skipped_encoder_samples.value_or(0) > 0) {
    show("skipped frames", metrics.skipped_frames, "(time not after the row before)");
    show("skipped encoder samples", metrics.skipped_encoder_samples, "(the same)");
  }
  if (metrics.reentries && *metrics.reentries > 0) {
    show("returns onto the map", metrics.reentries, "");
    show("  frames to first fix", metrics.reentry_frames_to_fix_max, "max");
    show("  first fix error", metrics.reentry_first_fix_error_max_mm, "mm max");
  }
  std::printf(" without ground truth:\n");
  show("path length (estimate)", metrics.estimate_path_length_m, "m");
  show("mean speed", metrics.estimate_speed_mean_mps, "m/s");
  show("speed p99", metrics.estimate_speed_p99_mps, "m/s");
  // Fixes of frames, per lock state and per mode: where the drive lost its fixes.
  const auto per = [](const char* name, const std::map<std::string, std::int64_t>& frames,
                      const std::map<std::string, std::int64_t>& fixes) {
    if (frames.empty()) return;
    std::string text;
    for (const auto& [what, count] : frames) {
      const auto fixed = fixes.find(what);
      text += (text.empty() ? "" : ", ") + what + " " + std::to_string(fixed == fixes.end() ? 0 : fixed->second) +
              "/" + std::to_string(count);
    }
    std::printf("  %-24s %s\n", name, text.c_str());
  };
  per("fixes/frames by state", metrics.frames_by_state, metrics.fixes_by_state);
  per("fixes/frames by mode", metrics.frames_by_mode, metrics.fixes_by_mode);
  if (!metrics.no_fix_reasons.empty()) {
    std::string reasons;
    for (const auto& [reason, count] : metrics.no_fix_reasons) {
      reasons += (reasons.empty() ? "" : ", ") + reason + " " + std::to_string(count);
    }
    std::printf("  %-24s %s\n", "frames without a fix", reasons.c_str());
  }
  if (metrics.nis_inside_95_share) {
    show("NIS inside 95 % bound", std::optional<double>(100.0 * *metrics.nis_inside_95_share), "% of fixes");
  }
  show("NIS mean (3: consistent)", metrics.nis_mean, "");
  if (metrics.nis_inside_95_share && *metrics.nis_inside_95_share < 0.9) {
    std::printf("  %-24s %s\n", "", "the filter's covariance understates its errors: fixes will be rejected");
  } else if (metrics.nis_mean && *metrics.nis_mean < 1.0) {
    std::printf("  %-24s %s\n", "", "the filter's covariance is pessimistic (safe, but the gate admits more)");
  }
  show("revisit repeatability", metrics.revisit_repeatability_mm, "mm");
  if (metrics.revisit_places) show("  revisited places", metrics.revisit_places, "");
  if (metrics.revisit_failures && *metrics.revisit_failures > 0) {
    show("  visits not registered", metrics.revisit_failures, "(frames that disagree with their estimates)");
  }
  std::printf(" against ground truth:\n");
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
