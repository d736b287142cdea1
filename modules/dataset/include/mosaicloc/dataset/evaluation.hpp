#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/core/timestamp.hpp"
#include "mosaicloc/dataset/trajectory.hpp"

namespace mosaicloc::dataset {

struct EvaluationOptions {
  /// An estimate is compared only where the ground-truth samples around it are at most this
  /// far apart in time (longer gaps are not interpolated).
  core::Duration max_gap = std::chrono::milliseconds(100);
  /// A ground-truth position within this distance of a repeatability place visits it [mm].
  double repeatability_radius_mm = 10.0;
  /// Path length between repeatability places along the ground truth [mm].
  double repeatability_spacing_mm = 100.0;

  /// False, with the reason in *why (if not null), when a value is not finite and positive.
  bool Check(std::string* why) const;
};

/// One estimate compared with the ground truth interpolated at its time.
struct ErrorSample {
  core::Timestamp time;
  core::Pose2 estimate;     ///< world_from_vehicle, estimated
  core::Pose2 groundtruth;  ///< world_from_vehicle, reference
  /// |estimate - groundtruth| of the positions [mm].
  double position_error_mm = 0.0;
  /// estimate yaw - groundtruth yaw, wrapped to (-pi, pi] [rad].
  double heading_error_rad = 0.0;
};

/// The replay report (design.md section 4, metrics.json). Empty means unknown (null in JSON).
struct Metrics {
  // --- design.md section 4 keys ---
  std::optional<std::int64_t> frames;       ///< images processed (Evaluate: number of estimates)
  std::optional<std::int64_t> fixes;        ///< visual fixes accepted (caller)
  std::optional<double> fix_rate;           ///< fixes / frames, 0..1 (caller)
  std::optional<std::int64_t> lock_losses;  ///< times the visual lock was lost (caller)
  std::optional<std::int64_t> wrong_fixes;  ///< visual fixes more than 1 mm from the truth (caller, CheckFixes)
  std::optional<double> max_wrong_fix_mm;   ///< the largest of those errors, 0 without one (caller)
  std::optional<double> position_rms_mm;    ///< RMS of position errors
  std::optional<double> position_p50_mm;    ///< median position error (percentile, see Evaluate)
  std::optional<double> position_p99_mm;    ///< 99th percentile of position errors
  std::optional<double> position_max_mm;    ///< largest position error
  std::optional<double> heading_rms_deg;    ///< RMS of heading errors [deg]
  std::optional<double> heading_max_deg;    ///< largest |heading error| [deg]
  std::optional<double> repeatability_mm;   ///< spread at revisited places (see Evaluate)
  std::optional<double> processing_fps;     ///< frames per second of processing time (caller)
  std::optional<double> latency_p50_ms;     ///< median image-to-fix latency (caller)
  std::optional<double> latency_p99_ms;     ///< 99th percentile latency (caller)
  std::optional<double> max_speed_mps;      ///< highest ground-truth speed [m/s]
  std::optional<double>
      overlap_speed_limit_mps;  ///< speed at which images stop overlapping (caller)
  // --- extras, written after the design keys ---
  std::optional<std::int64_t> associated;         ///< estimates compared with ground truth
  std::optional<double> final_position_error_mm;  ///< position error of the last compared estimate
  std::optional<double> path_length_m;  ///< ground-truth path length over the compared span
  std::optional<double> drift_percent;  ///< 100 final_position_error / path_length
  std::optional<std::int64_t> repeatability_places;  ///< places visited at least twice
  std::optional<double> fix_error_rms_mm;  ///< RMS error of the visual fixes themselves (caller)
  std::optional<std::int64_t> off_map_frames;        ///< frames reported off the map (caller)
  std::optional<std::int64_t> skipped_frames;           ///< recording rows skipped: not after the row before (caller)
  std::optional<std::int64_t> skipped_encoder_samples;  ///< the same for encoder samples (caller)
  std::optional<double> off_map_max_error_mm;  ///< largest dead-reckoning error while off the map (caller)
  /// Returns onto the map (the true view wholly on it after some frames that were not), the
  /// most frames any of them took to the first fix, and the largest error of those first
  /// fixes (caller).
  std::optional<std::int64_t> reentries;
  std::optional<std::int64_t> reentry_frames_to_fix_max;
  std::optional<double> reentry_first_fix_error_max_mm;
  std::optional<std::int64_t> relocalizations;  ///< filter restarts at a place found by a search (caller)
  /// Filter restarts on fixes the gate kept rejecting by the same offset (caller).
  std::optional<std::int64_t> reanchorings;
  /// What the filter learnt of the vehicle's calibration by the end (caller; written when set):
  /// a differential drive's wheel scale errors, a tricycle's drive wheel scale error and the
  /// error of its calibrated steering offset, a mecanum vehicle's wheel scale error and its
  /// sideways motion's. A figure that persists is one to recalibrate.
  std::optional<double> wheel_scale_left_percent, wheel_scale_right_percent;
  std::optional<double> drive_wheel_scale_percent, steering_offset_error_deg;
  std::optional<double> wheel_scale_percent, lateral_scale_percent;
  /// Frames from the first to the first fix, and the seconds between them (caller).
  std::optional<std::int64_t> frames_to_first_fix;
  std::optional<double> first_fix_s;
  /// A kidnap (replay --kidnap-at): frames from it to the first fix after it (caller).
  std::optional<std::int64_t> kidnap_frames_to_fix;
  /// Automatic mapping (replay --mapping; caller): stretches committed, of them closed onto
  /// the map at both ends, frames painted, level-0 tiles written, frames off the map not mapped
  /// (no confident keyframe to start from), the largest correction a return made, mm; with
  /// ground truth the painted frames' vehicle position error, RMS and largest, mm.
  std::optional<std::int64_t> map_extension_segments;
  std::optional<std::int64_t> map_extension_closed;
  std::optional<std::int64_t> map_extension_keyframes;
  std::optional<std::int64_t> map_extension_tiles;
  std::optional<std::int64_t> map_extension_unanchored;
  std::optional<std::int64_t> map_extension_bridged;
  std::optional<double> map_extension_closure_max_mm;
  std::optional<double> map_extension_pose_rms_mm;
  std::optional<double> map_extension_pose_max_mm;
  /// Frames off the map faster than the overlap speed limit, and the fastest speed off it, m/s.
  std::optional<std::int64_t> map_extension_overspeed_frames;
  std::optional<double> map_extension_speed_max_mps;
  /// Automatic map updates (replay --mapping; caller, design.md section 7e).
  struct MapUpdateFigures {
    std::int64_t updates = 0;         ///< written, each one transaction in the map's history
    std::int64_t cells = 0;           ///< cells rewritten
    std::int64_t tiles = 0;           ///< level-0 tiles written
    std::int64_t pending_cells = 0;   ///< seen changed, not on enough passes (yet)
    std::int64_t compared = 0;        ///< confident frames compared with the map
    std::int64_t mostly_changed = 0;  ///< ... that looked changed over too much of the view to vote
    std::int64_t repeating = 0;       ///< confident frames not compared: the floor under them repeats
    /// With ground truth: the largest position error of a frame an update was painted from, mm.
    std::optional<double> pose_max_mm;
  };
  std::optional<MapUpdateFigures> map_update;
  /// The camera's height the localizer held at its fixes (image scale x calibrated height)
  /// against the simulator's truth (groundtruth/camera.csv), mm (caller).
  std::optional<double> height_error_rms_mm;
  std::optional<double> height_error_max_mm;
  // --- figures without ground truth (dataset/validation.hpp; runtime/revisits.hpp) ---
  /// The estimate's own path length, its mean speed over the drive and the 99th percentile
  /// of its frame-to-frame speeds.
  std::optional<double> estimate_path_length_m;
  std::optional<double> estimate_speed_mean_mps;
  std::optional<double> estimate_speed_p99_mps;
  /// Frames and fixes per lock state ("tracking", "degraded", "lost", "off-map",
  /// "searching"; "none" in the baseline modes), and frames without a fix per reason.
  std::map<std::string, std::int64_t> frames_by_state;
  std::map<std::string, std::int64_t> fixes_by_state;
  std::map<std::string, std::int64_t> no_fix_reasons;
  /// Frames and fixes per mode (fixes.csv's mode column), and how often the mode changed.
  std::map<std::string, std::int64_t> frames_by_mode;
  std::map<std::string, std::int64_t> fixes_by_mode;
  std::optional<std::int64_t> mode_switches;
  /// The filter's consistency: fixes it judged, the share of their normalized innovation
  /// squared (NIS) inside the chi-square 95 % bound for 3 degrees of freedom (7.81), the mean
  /// NIS (3 for a filter whose covariances are true), and the standard deviation of each
  /// innovation component (x, y, yaw) over its predicted one (1 when true).
  std::optional<std::int64_t> nis_fixes;
  std::optional<double> nis_inside_95_share;
  std::optional<double> nis_mean;
  std::optional<Eigen::Vector3d> innovation_sigma_ratio;
  /// The repeatability of the camera's centre at the frames with a fix (the point the fixes
  /// measure), as repeatability_mm defines it, against the truth; and the places it rests on.
  std::optional<double> repeatability_camera_mm;
  std::optional<std::int64_t> repeatability_camera_places;
  /// The same from the recording alone: at places the camera passes more than once, each
  /// later visit's frame registered to the first visit's, against where the two estimates put
  /// it (runtime/revisits.hpp); with the places and visits it rests on and the visits whose
  /// registration failed.
  std::optional<double> revisit_repeatability_mm;
  std::optional<std::int64_t> revisit_places;
  std::optional<std::int64_t> revisit_visits;
  std::optional<std::int64_t> revisit_failures;
};

struct Evaluation {
  std::vector<ErrorSample> samples;  ///< the associated estimates, in time order
  Metrics metrics;
};

/// The percent-th percentile of ascending, non-empty `sorted`, interpolating linearly between
/// closest ranks (NumPy's default), as every report figure uses.
double Percentile(const std::vector<double>& sorted, double percent);

/// Associates each estimate with the ground truth interpolated at its time (PoseAt with
/// options.max_gap: estimates outside the ground truth's time range, or inside a gap longer than
/// max_gap, are left out) and computes the errors and metrics.
///
/// Fills frames (number of estimates), associated, position_* and heading_* statistics,
/// repeatability, max_speed_mps and the extras. Leaves fixes, fix_rate, lock_losses,
/// processing_fps, latency_* and overlap_speed_limit_mps empty for the caller.
///
/// Percentiles interpolate linearly between closest ranks (NumPy's default): with the n errors
/// sorted e_0 <= ... <= e_(n-1), the p-th percentile at h = (n - 1) p / 100 is
/// e_floor(h) + (h - floor(h)) (e_ceil(h) - e_floor(h)). Heading statistics use |heading error|.
///
/// max_speed_mps: the highest |Δposition| / Δt over consecutive ground-truth samples whose
/// interval meets the compared time span and is at most max_gap long.
/// path_length_m: ground-truth path length from the first to the last compared time.
///
/// Repeatability, the spread of the estimates at the same ground-truth place over repeated
/// passes (a sample here is an associated estimate, in time order):
///  1. Places: walking along the samples' ground-truth positions, a candidate place is taken at
///     the first sample and then whenever repeatability_spacing_mm of path length has been
///     travelled since the last candidate; a candidate closer than spacing / 2 to an existing
///     place is dropped, so repeated passes share the first pass's places.
///  2. Visits: a visit of a place is a maximal run of consecutive samples whose ground truth
///     lies within repeatability_radius_mm of it; the run's sample nearest the place stands for it.
///  3. For every place with k >= 2 visits, with error vectors e_j = estimate - groundtruth
///     position (world frame) of its visits and their mean m, the deviations |e_j - m| are
///     collected; repeatability_mm = sqrt(mean of the squared deviations over all visits of all
///     such places) (for two visits of every place: half the distance between the two errors).
///     Empty when no place is visited twice (a single pass, a straight run).
/// Places are found through a hash grid: linear time in the number of samples.
///
/// Throws core::Error (invalid input) when the options fail Check, a trajectory is empty or
/// not sorted, or no estimate can be associated (the message gives both time ranges).
Evaluation Evaluate(const Trajectory& estimate, const Trajectory& groundtruth,
                    const EvaluationOptions& options);

/// The caller's metrics with an evaluation's figures against the truth (what Evaluate fills),
/// the caller's frame count kept where it has one.
Metrics WithEvaluation(Metrics metrics, const Metrics& evaluated);

/// Places passed more than once along `positions` (time order), found as Evaluate's
/// repeatability finds them (steps 1 and 2): for every place, the indices of the positions that
/// stand for its visits.
std::vector<std::vector<std::size_t>> RevisitedPlaces(const std::vector<Eigen::Vector2d>& positions,
                                                      const EvaluationOptions& options);

/// Evaluate's repeatability (step 3) of error vectors grouped by place: places with fewer than
/// two are skipped; empty when no place has two.
struct PlaceSpread {
  double rms_mm = 0.0;
  std::int64_t places = 0;
  std::int64_t visits = 0;
};
std::optional<PlaceSpread> SpreadAtPlaces(const std::vector<std::vector<Eigen::Vector2d>>& errors);

/// metrics.json's object: every design.md section 4 key in that order, null where unknown, then
/// the extras.
nlohmann::ordered_json MetricsJson(const Metrics& metrics);
/// Writes metrics.json (MetricsJson), pretty-printed, atomically (temporary file, then rename).
/// Throws core::Error (runtime) if writing fails.
void WriteMetricsJson(const std::filesystem::path& file, const Metrics& metrics);

}  // namespace mosaicloc::dataset
