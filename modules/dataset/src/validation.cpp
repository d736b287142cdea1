#include "mosaicloc/dataset/validation.hpp"

#include <algorithm>
#include <cmath>

namespace mosaicloc::dataset {

const char* StatusName(int status) {
  switch (status) {
    case 0: return "none";
    case 1: return "tracking";
    case 2: return "degraded";
    case 3: return "lost";
    case 4: return "off-map";
    case 5: return "searching";
    default: return "unknown";
  }
}

void AddTruthFreeFigures(const std::vector<FrameReport>& reports, const Trajectory& estimate,
                         const std::vector<Eigen::Vector3d>& normalized_innovations, Metrics* metrics) {
  if (estimate.size() >= 2) {
    double length_mm = 0.0;
    std::vector<double> speeds_mps;
    speeds_mps.reserve(estimate.size() - 1);
    for (std::size_t i = 1; i < estimate.size(); ++i) {
      const double step_mm = core::Distance(estimate[i - 1].world_from_vehicle, estimate[i].world_from_vehicle);
      length_mm += step_mm;
      const double dt_s = core::ToSeconds(estimate[i].time - estimate[i - 1].time);
      if (dt_s > 0.0) speeds_mps.push_back(step_mm / dt_s / 1000.0);
    }
    const double duration_s = core::ToSeconds(estimate.back().time - estimate.front().time);
    metrics->estimate_path_length_m = length_mm / 1000.0;
    if (duration_s > 0.0) metrics->estimate_speed_mean_mps = length_mm / duration_s / 1000.0;
    if (!speeds_mps.empty()) {
      std::sort(speeds_mps.begin(), speeds_mps.end());
      metrics->estimate_speed_p99_mps = Percentile(speeds_mps, 99.0);
    }
  }

  metrics->frames_by_state.clear();
  metrics->fixes_by_state.clear();
  metrics->no_fix_reasons.clear();
  metrics->frames_by_mode.clear();
  metrics->fixes_by_mode.clear();
  metrics->mode_switches.reset();
  const std::string* last_mode = nullptr;
  double nis_sum = 0.0;
  std::int64_t nis_count = 0;
  std::int64_t nis_inside = 0;
  for (const FrameReport& report : reports) {
    const std::string state = StatusName(report.status);
    ++metrics->frames_by_state[state];
    if (!report.mode.empty()) {
      ++metrics->frames_by_mode[report.mode];
      if (!metrics->mode_switches) metrics->mode_switches = 0;
      if (last_mode != nullptr && *last_mode != report.mode) ++*metrics->mode_switches;
      last_mode = &report.mode;
    }
    if (report.fixed) {
      ++metrics->fixes_by_state[state];
      if (!report.mode.empty()) ++metrics->fixes_by_mode[report.mode];
    } else {
      ++metrics->no_fix_reasons[report.reason.empty() ? std::string("unknown") : report.reason];
    }
    if (report.nis) {
      ++nis_count;
      nis_sum += *report.nis;
      if (*report.nis <= kNis95Bound3Dof) ++nis_inside;
    }
  }
  if (nis_count > 0) {
    metrics->nis_fixes = nis_count;
    metrics->nis_inside_95_share = static_cast<double>(nis_inside) / static_cast<double>(nis_count);
    metrics->nis_mean = nis_sum / static_cast<double>(nis_count);
  }
  if (normalized_innovations.size() >= 2) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const Eigen::Vector3d& v : normalized_innovations) mean += v;
    mean /= static_cast<double>(normalized_innovations.size());
    Eigen::Vector3d sum_sq = Eigen::Vector3d::Zero();
    for (const Eigen::Vector3d& v : normalized_innovations) sum_sq += (v - mean).cwiseAbs2();
    metrics->innovation_sigma_ratio =
        (sum_sq / static_cast<double>(normalized_innovations.size() - 1)).cwiseSqrt().eval();
  }
}

}  // namespace mosaicloc::dataset
