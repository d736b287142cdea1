#include "mosaicloc/dataset/evaluation.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string_view>
#include <unordered_map>

#include <nlohmann/json.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/file.hpp"
#include "mosaicloc/core/log.hpp"

namespace mosaicloc::dataset {

namespace {

constexpr double kDegPerRad = 180.0 / std::numbers::pi;

double Rms(const std::vector<double>& values) {
  double sum = 0.0;
  for (double v : values) sum += v * v;
  return std::sqrt(sum / static_cast<double>(values.size()));
}

std::string Span(const Trajectory& trajectory) {
  return "[" + FormatSeconds(trajectory.front().time) + " s, " +
         FormatSeconds(trajectory.back().time) + " s]";
}

void CheckTrajectory(const Trajectory& trajectory, const std::string& name) {
  if (trajectory.empty())
    core::ThrowInvalidInput("evaluation: the " + name + " trajectory is empty");
  for (std::size_t i = 1; i < trajectory.size(); ++i) {
    if (trajectory[i].time <= trajectory[i - 1].time) {
      core::ThrowInvalidInput("evaluation: the " + name +
                              " trajectory's time does not strictly "
                              "increase at pose " +
                              std::to_string(i) + " (" + FormatSeconds(trajectory[i].time) +
                              " s after " + FormatSeconds(trajectory[i - 1].time) + " s)");
    }
  }
}

// Points bucketed in square cells; a query within the cell size looks at the 3 x 3 cells around.
class HashGrid {
 public:
  explicit HashGrid(double cell_mm) : cell_mm_(cell_mm) {}

  void Insert(const Eigen::Vector2d& point_mm, std::size_t id) {
    cells_[Key(Cell(point_mm.x()), Cell(point_mm.y()))].push_back(id);
  }

  template <typename Visit>
  void ForEachNear(const Eigen::Vector2d& point_mm, Visit&& visit) const {
    const std::int64_t cx = Cell(point_mm.x());
    const std::int64_t cy = Cell(point_mm.y());
    for (std::int64_t dy = -1; dy <= 1; ++dy) {
      for (std::int64_t dx = -1; dx <= 1; ++dx) {
        const auto found = cells_.find(Key(cx + dx, cy + dy));
        if (found == cells_.end()) continue;
        for (std::size_t id : found->second) visit(id);
      }
    }
  }

 private:
  std::int64_t Cell(double coordinate_mm) const {
    return static_cast<std::int64_t>(std::floor(coordinate_mm / cell_mm_));
  }
  static std::uint64_t Key(std::int64_t cx, std::int64_t cy) {
    return (static_cast<std::uint64_t>(cx) << 32) ^
           (static_cast<std::uint64_t>(cy) & 0xffffffffULL);
  }

  double cell_mm_;
  std::unordered_map<std::uint64_t, std::vector<std::size_t>> cells_;
};

}  // namespace

std::vector<std::vector<std::size_t>> RevisitedPlaces(const std::vector<Eigen::Vector2d>& positions,
                                                      const EvaluationOptions& options) {
  const double radius = options.repeatability_radius_mm;
  const double spacing = options.repeatability_spacing_mm;
  HashGrid grid(std::max(radius, spacing / 2.0));

  std::vector<Eigen::Vector2d> places;
  double travelled_mm = 0.0;
  double next_candidate_mm = 0.0;
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const Eigen::Vector2d& position = positions[i];
    if (i > 0) travelled_mm += (position - positions[i - 1]).norm();
    if (travelled_mm < next_candidate_mm) continue;
    next_candidate_mm = travelled_mm + spacing;
    bool near_existing = false;
    grid.ForEachNear(position, [&](std::size_t id) {
      near_existing = near_existing || (places[id] - position).norm() < spacing / 2.0;
    });
    if (near_existing) continue;
    grid.Insert(position, places.size());
    places.push_back(position);
  }

  struct Run {
    std::size_t last = 0;
    std::size_t best = 0;
    double best_distance_mm = 0.0;
    bool open = false;
  };
  std::vector<Run> runs(places.size());
  std::vector<std::vector<std::size_t>> visits(places.size());
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const Eigen::Vector2d& position = positions[i];
    grid.ForEachNear(position, [&](std::size_t id) {
      const double distance_mm = (places[id] - position).norm();
      if (distance_mm > radius) return;
      Run& run = runs[id];
      if (run.open && run.last + 1 == i) {
        if (distance_mm < run.best_distance_mm) {
          run.best = i;
          run.best_distance_mm = distance_mm;
        }
      } else {
        if (run.open) visits[id].push_back(run.best);
        run.open = true;
        run.best = i;
        run.best_distance_mm = distance_mm;
      }
      run.last = i;
    });
  }
  for (std::size_t id = 0; id < places.size(); ++id) {
    if (runs[id].open) visits[id].push_back(runs[id].best);
  }
  return visits;
}

std::optional<PlaceSpread> SpreadAtPlaces(const std::vector<std::vector<Eigen::Vector2d>>& errors) {
  PlaceSpread spread;
  double sum_squared_mm2 = 0.0;
  for (const std::vector<Eigen::Vector2d>& place : errors) {
    if (place.size() < 2) continue;
    ++spread.places;
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (const Eigen::Vector2d& error : place) mean += error;
    mean /= static_cast<double>(place.size());
    for (const Eigen::Vector2d& error : place) {
      sum_squared_mm2 += (error - mean).squaredNorm();
      ++spread.visits;
    }
  }
  if (spread.places == 0) return std::nullopt;
  spread.rms_mm = std::sqrt(sum_squared_mm2 / static_cast<double>(spread.visits));
  return spread;
}

namespace {

// The definition is in evaluation.hpp (Evaluate).
std::optional<PlaceSpread> ComputeRepeatability(const std::vector<ErrorSample>& samples,
                                                const EvaluationOptions& options) {
  if (samples.size() < 2) return std::nullopt;
  std::vector<Eigen::Vector2d> truth;
  truth.reserve(samples.size());
  for (const ErrorSample& sample : samples) truth.push_back(sample.groundtruth.translation_mm());
  std::vector<std::vector<Eigen::Vector2d>> errors;
  for (const std::vector<std::size_t>& visits : RevisitedPlaces(truth, options)) {
    if (visits.size() < 2) continue;
    errors.emplace_back();
    for (std::size_t i : visits) {
      errors.back().push_back(samples[i].estimate.translation_mm() - samples[i].groundtruth.translation_mm());
    }
  }
  return SpreadAtPlaces(errors);
}

// Ground-truth path length [mm] from time `from` to time `to` (both inside the trajectory):
// the interpolated end poses joined through the samples strictly between them.
double PathLengthMm(const Trajectory& groundtruth, const ErrorSample& from, const ErrorSample& to) {
  const auto by_time = [](const StampedPose& pose, core::Timestamp time) {
    return pose.time < time;
  };
  auto it = std::upper_bound(
      groundtruth.begin(), groundtruth.end(), from.time,
      [](core::Timestamp time, const StampedPose& pose) { return time < pose.time; });
  const auto end = std::lower_bound(groundtruth.begin(), groundtruth.end(), to.time, by_time);
  double length_mm = 0.0;
  Eigen::Vector2d previous = from.groundtruth.translation_mm();
  for (; it < end; ++it) {
    length_mm += (it->world_from_vehicle.translation_mm() - previous).norm();
    previous = it->world_from_vehicle.translation_mm();
  }
  return length_mm + (to.groundtruth.translation_mm() - previous).norm();
}

std::optional<double> MaxSpeedMps(const Trajectory& groundtruth, core::Timestamp from,
                                  core::Timestamp to, core::Duration max_gap) {
  std::optional<double> fastest;
  for (std::size_t i = 1; i < groundtruth.size(); ++i) {
    const StampedPose& a = groundtruth[i - 1];
    const StampedPose& b = groundtruth[i];
    if (b.time < from || a.time > to || b.time - a.time > max_gap) continue;
    // mm per second / 1000 = m/s
    const double speed_mps = core::Distance(a.world_from_vehicle, b.world_from_vehicle) /
                             core::ToSeconds(b.time - a.time) / 1000.0;
    fastest = std::max(fastest.value_or(0.0), speed_mps);
  }
  return fastest;
}

// A count per name; null when there is none.
nlohmann::ordered_json ToJson(const std::map<std::string, std::int64_t>& counts) {
  if (counts.empty()) return nullptr;
  nlohmann::ordered_json json = nlohmann::ordered_json::object();
  for (const auto& [name, count] : counts) json[name] = count;
  return json;
}

template <typename T>
nlohmann::ordered_json ToJson(const std::optional<T>& value) {
  return value ? nlohmann::ordered_json(*value) : nlohmann::ordered_json(nullptr);
}

}  // namespace

double Percentile(const std::vector<double>& sorted, double percent) {
  const double h = static_cast<double>(sorted.size() - 1) * percent / 100.0;
  const auto below = static_cast<std::size_t>(std::floor(h));
  const std::size_t above = std::min(below + 1, sorted.size() - 1);
  return sorted[below] + (h - static_cast<double>(below)) * (sorted[above] - sorted[below]);
}

bool EvaluationOptions::Check(std::string* why) const {
  std::string reason;
  if (max_gap.count() <= 0) {
    reason = "max_gap must be positive";
  } else if (!std::isfinite(repeatability_radius_mm) || repeatability_radius_mm <= 0.0) {
    reason = "repeatability_radius_mm must be finite and positive";
  } else if (!std::isfinite(repeatability_spacing_mm) || repeatability_spacing_mm <= 0.0) {
    reason = "repeatability_spacing_mm must be finite and positive";
  }
  if (why != nullptr) *why = reason;
  return reason.empty();
}

Evaluation Evaluate(const Trajectory& estimate, const Trajectory& groundtruth,
                    const EvaluationOptions& options) {
  std::string why;
  if (!options.Check(&why)) core::ThrowInvalidInput("evaluation options: " + why);
  CheckTrajectory(estimate, "estimate");
  CheckTrajectory(groundtruth, "ground-truth");

  Evaluation evaluation;
  evaluation.samples.reserve(estimate.size());
  for (const StampedPose& pose : estimate) {
    const std::optional<core::Pose2> reference = PoseAt(groundtruth, pose.time, options.max_gap);
    if (!reference) continue;
    evaluation.samples.push_back({pose.time, pose.world_from_vehicle, *reference,
                                  core::Distance(pose.world_from_vehicle, *reference),
                                  core::YawDifference(pose.world_from_vehicle, *reference)});
  }
  if (evaluation.samples.empty()) {
    const bool overlap = estimate.front().time <= groundtruth.back().time &&
                         groundtruth.front().time <= estimate.back().time;
    core::ThrowInvalidInput(
        "evaluation: no estimate could be compared with the ground truth: the estimate spans " +
        Span(estimate) + ", the ground truth spans " + Span(groundtruth) +
        (overlap ? "; every estimate falls in a ground-truth gap longer than max_gap (" +
                       std::to_string(core::ToSeconds(options.max_gap)) + " s)"
                 : "; the time ranges do not overlap (are both from the same clock?)"));
  }

  if (evaluation.samples.size() < estimate.size()) {
    core::Log().warn(
        "evaluation: {} of {} estimates are outside the ground truth or in a gap longer than {} s, "
        "and are not compared",
        estimate.size() - evaluation.samples.size(), estimate.size(),
        core::ToSeconds(options.max_gap));
  }
  const std::vector<ErrorSample>& samples = evaluation.samples;
  std::vector<double> position_mm;
  std::vector<double> heading_deg;
  position_mm.reserve(samples.size());
  heading_deg.reserve(samples.size());
  for (const ErrorSample& sample : samples) {
    position_mm.push_back(sample.position_error_mm);
    heading_deg.push_back(std::abs(sample.heading_error_rad) * kDegPerRad);
  }
  std::sort(position_mm.begin(), position_mm.end());

  Metrics& metrics = evaluation.metrics;
  metrics.frames = static_cast<std::int64_t>(estimate.size());
  metrics.associated = static_cast<std::int64_t>(samples.size());
  metrics.position_rms_mm = Rms(position_mm);
  metrics.position_p50_mm = Percentile(position_mm, 50.0);
  metrics.position_p99_mm = Percentile(position_mm, 99.0);
  metrics.position_max_mm = position_mm.back();
  metrics.heading_rms_deg = Rms(heading_deg);
  metrics.heading_max_deg = *std::max_element(heading_deg.begin(), heading_deg.end());
  if (const auto repeatability = ComputeRepeatability(samples, options)) {
    metrics.repeatability_mm = repeatability->rms_mm;
    metrics.repeatability_places = repeatability->places;
  } else {
    metrics.repeatability_places = 0;
  }
  metrics.max_speed_mps =
      MaxSpeedMps(groundtruth, samples.front().time, samples.back().time, options.max_gap);
  metrics.final_position_error_mm = samples.back().position_error_mm;
  const double path_length_mm = PathLengthMm(groundtruth, samples.front(), samples.back());
  metrics.path_length_m = path_length_mm / 1000.0;
  if (path_length_mm > 0.0) {
    metrics.drift_percent = 100.0 * samples.back().position_error_mm / path_length_mm;
  }
  return evaluation;
}

Metrics WithEvaluation(Metrics metrics, const Metrics& evaluated) {
  if (!metrics.frames) metrics.frames = evaluated.frames;
  metrics.associated = evaluated.associated;
  metrics.position_rms_mm = evaluated.position_rms_mm;
  metrics.position_p50_mm = evaluated.position_p50_mm;
  metrics.position_p99_mm = evaluated.position_p99_mm;
  metrics.position_max_mm = evaluated.position_max_mm;
  metrics.heading_rms_deg = evaluated.heading_rms_deg;
  metrics.heading_max_deg = evaluated.heading_max_deg;
  metrics.repeatability_mm = evaluated.repeatability_mm;
  metrics.repeatability_places = evaluated.repeatability_places;
  metrics.max_speed_mps = evaluated.max_speed_mps;
  metrics.final_position_error_mm = evaluated.final_position_error_mm;
  metrics.path_length_m = evaluated.path_length_m;
  metrics.drift_percent = evaluated.drift_percent;
  return metrics;
}

nlohmann::ordered_json MetricsJson(const Metrics& metrics) {
  nlohmann::ordered_json json = nlohmann::ordered_json::object();
  json["frames"] = ToJson(metrics.frames);
  json["fixes"] = ToJson(metrics.fixes);
  json["fix_rate"] = ToJson(metrics.fix_rate);
  json["lock_losses"] = ToJson(metrics.lock_losses);
  json["wrong_fixes"] = ToJson(metrics.wrong_fixes);
  json["max_wrong_fix_mm"] = ToJson(metrics.max_wrong_fix_mm);
  json["position_rms_mm"] = ToJson(metrics.position_rms_mm);
  json["position_p50_mm"] = ToJson(metrics.position_p50_mm);
  json["position_p99_mm"] = ToJson(metrics.position_p99_mm);
  json["position_max_mm"] = ToJson(metrics.position_max_mm);
  json["heading_rms_deg"] = ToJson(metrics.heading_rms_deg);
  json["heading_max_deg"] = ToJson(metrics.heading_max_deg);
  json["repeatability_mm"] = ToJson(metrics.repeatability_mm);
  json["processing_fps"] = ToJson(metrics.processing_fps);
  json["latency_p50_ms"] = ToJson(metrics.latency_p50_ms);
  json["latency_p99_ms"] = ToJson(metrics.latency_p99_ms);
  json["max_speed_mps"] = ToJson(metrics.max_speed_mps);
  json["overlap_speed_limit_mps"] = ToJson(metrics.overlap_speed_limit_mps);
  json["associated"] = ToJson(metrics.associated);
  json["final_position_error_mm"] = ToJson(metrics.final_position_error_mm);
  json["path_length_m"] = ToJson(metrics.path_length_m);
  json["drift_percent"] = ToJson(metrics.drift_percent);
  json["repeatability_places"] = ToJson(metrics.repeatability_places);
  json["fix_error_rms_mm"] = ToJson(metrics.fix_error_rms_mm);
  json["off_map_frames"] = ToJson(metrics.off_map_frames);
  json["off_map_max_error_mm"] = ToJson(metrics.off_map_max_error_mm);
  json["skipped_frames"] = ToJson(metrics.skipped_frames);
  json["skipped_encoder_samples"] = ToJson(metrics.skipped_encoder_samples);
  json["reentries"] = ToJson(metrics.reentries);
  json["reentry_frames_to_fix_max"] = ToJson(metrics.reentry_frames_to_fix_max);
  json["reentry_first_fix_error_max_mm"] = ToJson(metrics.reentry_first_fix_error_max_mm);
  json["relocalizations"] = ToJson(metrics.relocalizations);
  json["reanchorings"] = ToJson(metrics.reanchorings);
  if (metrics.wheel_scale_left_percent) {
    json["wheel_scale_left_percent"] = ToJson(metrics.wheel_scale_left_percent);
    json["wheel_scale_right_percent"] = ToJson(metrics.wheel_scale_right_percent);
  }
  if (metrics.drive_wheel_scale_percent) {
    json["drive_wheel_scale_percent"] = ToJson(metrics.drive_wheel_scale_percent);
    json["steering_offset_error_deg"] = ToJson(metrics.steering_offset_error_deg);
  }
  if (metrics.wheel_scale_percent) {
    json["wheel_scale_percent"] = ToJson(metrics.wheel_scale_percent);
    json["lateral_scale_percent"] = ToJson(metrics.lateral_scale_percent);
  }
  json["frames_to_first_fix"] = ToJson(metrics.frames_to_first_fix);
  json["first_fix_s"] = ToJson(metrics.first_fix_s);
  json["kidnap_frames_to_fix"] = ToJson(metrics.kidnap_frames_to_fix);
  if (metrics.map_extension_segments) {
    json["map_extension_segments"] = ToJson(metrics.map_extension_segments);
    json["map_extension_closed"] = ToJson(metrics.map_extension_closed);
    json["map_extension_keyframes"] = ToJson(metrics.map_extension_keyframes);
    json["map_extension_tiles"] = ToJson(metrics.map_extension_tiles);
    json["map_extension_unanchored"] = ToJson(metrics.map_extension_unanchored);
    json["map_extension_bridged"] = ToJson(metrics.map_extension_bridged);
    json["map_extension_closure_max_mm"] = ToJson(metrics.map_extension_closure_max_mm);
    json["map_extension_pose_rms_mm"] = ToJson(metrics.map_extension_pose_rms_mm);
    json["map_extension_pose_max_mm"] = ToJson(metrics.map_extension_pose_max_mm);
    json["map_extension_overspeed_frames"] = ToJson(metrics.map_extension_overspeed_frames);
    json["map_extension_speed_max_mps"] = ToJson(metrics.map_extension_speed_max_mps);
  }
  if (const auto& u = metrics.map_update) {
    json["map_updates"] = u->updates;
    json["map_update_cells"] = u->cells;
    json["map_update_tiles"] = u->tiles;
    json["map_update_pending_cells"] = u->pending_cells;
    json["map_update_compared"] = u->compared;
    json["map_update_mostly_changed"] = u->mostly_changed;
    json["map_update_repeating"] = u->repeating;
    json["map_update_pose_max_mm"] = ToJson(u->pose_max_mm);
  }
  json["height_error_rms_mm"] = ToJson(metrics.height_error_rms_mm);
  json["height_error_max_mm"] = ToJson(metrics.height_error_max_mm);
  json["estimate_path_length_m"] = ToJson(metrics.estimate_path_length_m);
  json["estimate_speed_mean_mps"] = ToJson(metrics.estimate_speed_mean_mps);
  json["estimate_speed_p99_mps"] = ToJson(metrics.estimate_speed_p99_mps);
  json["frames_by_state"] = ToJson(metrics.frames_by_state);
  json["fixes_by_state"] = ToJson(metrics.fixes_by_state);
  json["no_fix_reasons"] = ToJson(metrics.no_fix_reasons);
  json["frames_by_mode"] = ToJson(metrics.frames_by_mode);
  json["fixes_by_mode"] = ToJson(metrics.fixes_by_mode);
  json["mode_switches"] = ToJson(metrics.mode_switches);
  json["nis_fixes"] = ToJson(metrics.nis_fixes);
  json["nis_inside_95_share"] = ToJson(metrics.nis_inside_95_share);
  json["nis_mean"] = ToJson(metrics.nis_mean);
  json["innovation_sigma_ratio"] =
      metrics.innovation_sigma_ratio
          ? nlohmann::ordered_json::array({metrics.innovation_sigma_ratio->x(), metrics.innovation_sigma_ratio->y(),
                                           metrics.innovation_sigma_ratio->z()})
          : nlohmann::ordered_json();
  json["repeatability_camera_mm"] = ToJson(metrics.repeatability_camera_mm);
  json["repeatability_camera_places"] = ToJson(metrics.repeatability_camera_places);
  json["revisit_repeatability_mm"] = ToJson(metrics.revisit_repeatability_mm);
  json["revisit_places"] = ToJson(metrics.revisit_places);
  json["revisit_visits"] = ToJson(metrics.revisit_visits);
  json["revisit_failures"] = ToJson(metrics.revisit_failures);
  return json;
}

void WriteMetricsJson(const std::filesystem::path& file, const Metrics& metrics) {
  core::WriteFileAtomically(file, MetricsJson(metrics).dump(2) + "\n");
}

}  // namespace mosaicloc::dataset
