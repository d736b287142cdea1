#include "mosaicloc/dataset/fixes.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>

#include <fmt/format.h>

#include "mosaicloc/core/error.hpp"
#include "text_fields.hpp"

namespace mosaicloc::dataset {
namespace {

constexpr std::size_t kFields = 12;
constexpr const char* kModes[] = {"track", "visual-odometry", "dead-reckoning", "searching"};

}  // namespace

std::string FixesCsvHeader() {
  return "#timestamp_ns,x_mm,y_mm,yaw_rad,status,quality,fix,sigma_mm,scale,nis,reason,mode\n";
}

std::string FixesCsvRow(const FrameReport& report) {
  if (report.reason.find_first_of(",\"\r\n") != std::string::npos) {
    core::ThrowInvalidInput("fixes.csv: reason '" + report.reason + "' holds a comma, quote or line break");
  }
  if (!report.mode.empty() && std::find(std::begin(kModes), std::end(kModes), report.mode) == std::end(kModes)) {
    core::ThrowInvalidInput("fixes.csv: mode '" + report.mode + "' is not one of the localizer's modes");
  }
  const std::string nis = report.nis && std::isfinite(*report.nis) ? fmt::format("{:.4g}", *report.nis) : "";
  return fmt::format("{},{:.4f},{:.4f},{:.7f},{},{},{},{:.4f},{:.6f},{},{},{}\n", report.time.nanoseconds(),
                     report.world_from_vehicle.x_mm(), report.world_from_vehicle.y_mm(),
                     report.world_from_vehicle.yaw_rad(), report.status,
                     static_cast<int>(std::lround(1000.0 * std::clamp(report.quality, 0.0, 1.0))),
                     report.fixed ? 1 : 0, report.sigma_mm, report.scale, nis, report.reason, report.mode);
}

std::vector<FrameReport> ReadFixesCsv(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) core::ThrowInvalidInput(file.string() + ": cannot open");
  std::vector<FrameReport> reports;
  std::string line;
  int number = 0;
  const auto number_of = [&](const std::string& text, const char* name) {
    const std::optional<double> value = detail::ParseDouble(text);
    if (!value || !std::isfinite(*value)) detail::LineError(file, number, std::string(name) + " '" + text + "' is not a number");
    return *value;
  };
  const auto integer_of = [&](const std::string& text, const char* name, std::int64_t lo, std::int64_t hi) {
    std::int64_t value = 0;
    if (!detail::ParseInt64(text, &value)) {
      detail::LineError(file, number, std::string(name) + " '" + text + "' is not an integer");
    }
    if (value < lo || value > hi) {
      detail::LineError(file, number, std::string(name) + " " + text + " is outside [" + std::to_string(lo) + ", " +
                                          std::to_string(hi) + "]");
    }
    return value;
  };
  while (std::getline(in, line)) {
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line.front() == '#') continue;
    const std::vector<std::string> f = detail::SplitCsv(line);
    if (f.size() > kFields || f.size() < kFields - 3) {
      detail::LineError(file, number,
                        std::to_string(f.size()) + " fields, " + std::to_string(kFields) +
                            " expected (timestamp_ns,x_mm,y_mm,yaw_rad,status,quality,fix,sigma_mm,scale,nis,reason,mode)");
    }
    FrameReport r;
    r.time = core::Timestamp::FromNanoseconds(integer_of(f[0], "timestamp_ns", std::numeric_limits<std::int64_t>::min(),
                                                          std::numeric_limits<std::int64_t>::max()));
    if (!reports.empty() && r.time <= reports.back().time) detail::LineError(file, number, "timestamp_ns does not increase");
    r.world_from_vehicle = core::Pose2(number_of(f[1], "x_mm"), number_of(f[2], "y_mm"), number_of(f[3], "yaw_rad"));
    r.status = static_cast<int>(integer_of(f[4], "status", 0, kMaxStatus));
    r.quality = static_cast<double>(integer_of(f[5], "quality", 0, 1000)) / 1000.0;
    r.fixed = integer_of(f[6], "fix", 0, 1) == 1;
    r.sigma_mm = number_of(f[7], "sigma_mm");
    if (r.sigma_mm < 0.0) detail::LineError(file, number, "sigma_mm is negative");
    if (f.size() >= kFields - 2) {
      r.scale = number_of(f[8], "scale");
      if (!(r.scale > 0.0 && r.scale < 2.0)) detail::LineError(file, number, "scale " + f[8] + " is outside (0, 2)");
    }
    if (f.size() >= kFields - 1 && !f[9].empty()) {
      r.nis = number_of(f[9], "nis");
      if (*r.nis < 0.0) detail::LineError(file, number, "nis is negative");
    }
    r.reason = f[f.size() == kFields ? kFields - 2 : f.size() - 1];
    if (f.size() == kFields) {
      r.mode = f.back();
      if (!r.mode.empty() && std::find(std::begin(kModes), std::end(kModes), r.mode) == std::end(kModes)) {
        detail::LineError(file, number, "mode '" + r.mode + "' is not one of track, visual-odometry, "
                                        "dead-reckoning, searching");
      }
    }
    reports.push_back(std::move(r));
  }
  return reports;
}

FixCheck CheckFixes(const std::vector<FrameReport>& reports, const Trajectory& groundtruth, double wrong_above_mm) {
  FixCheck check;
  double sum_sq = 0.0;
  for (const FrameReport& r : reports) {
    if (r.status == 4) ++check.off_map_frames;
    const std::optional<core::Pose2> truth = PoseAt(groundtruth, r.time, std::chrono::milliseconds(100));
    if (!truth) continue;
    const double error_mm = (r.world_from_vehicle.translation_mm() - truth->translation_mm()).norm();
    if (r.status == 4) check.off_map_max_error_mm = std::max(check.off_map_max_error_mm.value_or(0.0), error_mm);
    if (!r.fixed) continue;
    ++check.checked_fixes;
    sum_sq += error_mm * error_mm;
    check.max_fix_error_mm = std::max(check.max_fix_error_mm.value_or(0.0), error_mm);
    if (error_mm > wrong_above_mm) {
      ++check.wrong_fixes;
      check.max_wrong_fix_mm = std::max(check.max_wrong_fix_mm.value_or(0.0), error_mm);
    }
  }
  if (check.checked_fixes > 0) check.fix_error_rms_mm = std::sqrt(sum_sq / static_cast<double>(check.checked_fixes));
  return check;
}

ReentryCheck CheckReentries(const std::vector<FrameReport>& reports, const std::vector<double>& view_mapped,
                            const Trajectory& groundtruth, double on_share, double off_share) {
  if (reports.size() != view_mapped.size()) {
    core::ThrowInvalidInput("CheckReentries: " + std::to_string(reports.size()) + " reports, " +
                            std::to_string(view_mapped.size()) + " mapped shares");
  }
  ReentryCheck check;
  const std::size_t n = reports.size();
  std::size_t i = 0;
  while (i < n) {
    if (view_mapped[i] >= off_share) {
      ++i;
      continue;
    }
    // An excursion: the return R is the next frame wholly on the map.
    std::size_t last_off = i, r = i;
    for (; r < n && view_mapped[r] < on_share; ++r) {
      if (view_mapped[r] < off_share) last_off = r;
    }
    if (r == n) break;  // never came back
    ++check.reentries;
    std::size_t f = last_off + 1;
    while (f < n && !reports[f].fixed && (f < r || view_mapped[f] >= on_share)) ++f;
    const bool fixed = f < n && reports[f].fixed;
    const auto frames = fixed ? std::max<std::int64_t>(1, static_cast<std::int64_t>(f) - static_cast<std::int64_t>(r) + 1)
                              : static_cast<std::int64_t>(f - r);
    check.frames_to_fix_max = std::max(check.frames_to_fix_max.value_or(0), frames);
    if (fixed) {
      if (const auto truth = PoseAt(groundtruth, reports[f].time, std::chrono::milliseconds(100))) {
        const double error_mm = (reports[f].world_from_vehicle.translation_mm() - truth->translation_mm()).norm();
        check.first_fix_error_max_mm = std::max(check.first_fix_error_max_mm.value_or(0.0), error_mm);
      }
    }
    i = r + 1;
  }
  return check;
}

}  // namespace mosaicloc::dataset
