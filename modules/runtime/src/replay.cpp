#include "mosaicloc/runtime/replay.hpp"
#include "mosaicloc/runtime/map_keeping.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <limits>
#include <numbers>
#include <optional>
#include <string>
#include <system_error>
#include <unordered_map>
#include <vector>

#include <fmt/format.h>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/file.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/dataset/camera_truth.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/dataset/fixes.hpp"
#include "mosaicloc/dataset/html_report.hpp"
#include "mosaicloc/dataset/plots.hpp"
#include "mosaicloc/dataset/report_plots.hpp"
#include "mosaicloc/dataset/trajectory.hpp"
#include "mosaicloc/dataset/validation.hpp"
#include "mosaicloc/estimation/odometry.hpp"
#include "mosaicloc/localizer/localizer.hpp"
#include "mosaicloc/localizer/speed_limits.hpp"
#include "mosaicloc/runtime/drive.hpp"
#include "mosaicloc/runtime/map_jobs.hpp"
#include "mosaicloc/runtime/map_quality.hpp"
#include "mosaicloc/runtime/map_session.hpp"
#include "mosaicloc/runtime/report.hpp"
#include "mosaicloc/runtime/revisits.hpp"
#include "mosaicloc/runtime/settings.hpp"
#include "mosaicloc/tracking/tracker.hpp"

namespace mosaicloc::runtime {
namespace {

// Overlap speed limit of the run (localizer::SpeedLimits), at the run's mean frame period.
std::optional<double> OverlapSpeedLimit(const dataset::DatasetInfo& info, const dataset::Trajectory& estimate,
                                        double required_overlap) {
  if (estimate.size() < 2) return std::nullopt;
  const double period_s =
      core::ToSeconds(estimate.back().time - estimate.front().time) / static_cast<double>(estimate.size() - 1);
  localizer::SpeedLimitOptions setup;
  setup.width_px = info.camera.width_px;
  setup.height_px = info.camera.height_px;
  setup.mm_per_px = info.camera.mm_per_px;
  setup.frame_rate_hz = 1.0 / period_s;
  setup.travel_direction_rad = -info.camera.vehicle_from_camera.yaw_rad();
  setup.required_overlap = required_overlap;
  return localizer::AnalyseSpeedLimits(setup).overlap_limit_mps;
}

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The dataset's ground truth, in the map's frame when the options place the map in the truth's.
std::optional<dataset::Trajectory> TruthInMapFrame(const dataset::DatasetReader& reader, const ReplayOptions& options) {
  std::optional<dataset::Trajectory> truth = GroundTruthOf(reader);
  if (truth && options.truth_from_map) {
    const core::Pose2 map_from_truth = options.truth_from_map->Inverse();
    for (dataset::StampedPose& pose : *truth) pose.world_from_vehicle = map_from_truth * pose.world_from_vehicle;
  }
  return truth;
}

// What the localizer knew after a frame beyond its row of fixes.csv, for the consistency
// figures and the timelines.
struct FrameExtras {
  std::optional<Eigen::Vector3d> normalized_innovation;
  Eigen::Vector2d calibration{kNaN, kNaN};  ///< CalibrationErrorsShown
};

// What a replay mode records frame by frame, and the report made of it.
class ReplayRecord {
 public:
  ReplayRecord(const dataset::DatasetReader& reader, std::optional<dataset::Trajectory> groundtruth,
               const std::function<void(double)>& progress)
      : groundtruth_(std::move(groundtruth)), progress_(progress), total_frames_(reader.frame_rows()) {
    known_.skipped_frames = reader.skipped_frames();
    known_.skipped_encoder_samples = reader.skipped_encoder_samples();
  }

  /// One frame: the estimate at its time (if any) and the processing time, ms.
  void Frame(core::Timestamp time, const std::optional<core::Pose2>& world_from_vehicle, double ms) {
    ++frames_;
    last_estimate_.reset();
    if (world_from_vehicle) {
      estimate_.push_back({time, *world_from_vehicle});
      last_estimate_ = estimate_.back();
    }
    latency_ms_.push_back(ms);
    last_latency_ms_ = ms;
    processing_s_ += ms * 1e-3;
    if (frames_ % 16 == 0 && progress_) {
      progress_(std::min(1.0, static_cast<double>(frames_) / static_cast<double>(std::max<std::int64_t>(total_frames_, 1))));
    }
  }

  /// Figures only the caller knows, written with the others.
  dataset::Metrics& known() { return known_; }
  const std::vector<dataset::FrameReport>& reports() const { return reports_; }
  /// The estimate at the frames with a fix.
  const dataset::Trajectory& fixed_estimates() const { return fixed_estimates_; }

  /// What the localizer reported for a frame (a row of fixes.csv); `view_mapped`: the share
  /// of the true view the map covers there (mosaic mode with ground truth), for the returns.
  void Report(const dataset::FrameReport& report, std::optional<double> view_mapped = std::nullopt,
              const FrameExtras& extras = {}) {
    if (report.fixed) ++fixes_;
    if (report.fixed && last_estimate_ && last_estimate_->time == report.time) fixed_estimates_.push_back(*last_estimate_);
    fixes_csv_ += dataset::FixesCsvRow(report);
    if (extras.normalized_innovation) innovations_.push_back(*extras.normalized_innovation);
    timeline_extras_.push_back({last_latency_ms_, extras.calibration});
    reports_.push_back(report);
    if (view_mapped) view_mapped_.push_back(*view_mapped);
  }

  /// The map's picture under the drive, for the plots over the map.
  void SetFloor(dataset::FloorPicture floor) { floor_ = std::move(floor); }

  /// Writes fixes.csv, metrics.json, estimate.tum and the plots; the metrics written.
  dataset::Metrics Finish(const ReplayOptions& options, const dataset::DatasetInfo& info, double required_overlap,
                          std::optional<std::int64_t> lock_losses, const std::string& title,
                          std::optional<std::int64_t> relocalizations = std::nullopt,
                          std::optional<std::int64_t> reanchorings = std::nullopt) {
    if (estimate_.empty() && reports_.empty()) {
      core::ThrowInvalidInput(options.dataset.string() + ": no frame falls within the encoder samples");
    }
    dataset::Metrics metrics = known_;  // what the modes noted on the way
    metrics.frames = frames_;
    metrics.fixes = fixes_;
    metrics.fix_rate = static_cast<double>(fixes_) / static_cast<double>(frames_);
    metrics.lock_losses = lock_losses;
    metrics.relocalizations = relocalizations;
    metrics.reanchorings = reanchorings;
    dataset::AddTruthFreeFigures(reports_, estimate_, innovations_, &metrics);
    if (groundtruth_) {
      // Every fix checked against the truth: a lock that never broke proves nothing if it held
      // onto the wrong place.
      CameraRepeatability(info.camera.vehicle_from_camera, &metrics);
      const dataset::FixCheck check = dataset::CheckFixes(reports_, *groundtruth_);
      metrics.wrong_fixes = check.wrong_fixes;
      metrics.max_wrong_fix_mm = check.max_wrong_fix_mm.value_or(0.0);
      metrics.fix_error_rms_mm = check.fix_error_rms_mm;
      metrics.off_map_frames = check.off_map_frames;
      metrics.off_map_max_error_mm = check.off_map_max_error_mm;
      if (view_mapped_.size() == reports_.size()) {
        const dataset::ReentryCheck reentries = dataset::CheckReentries(reports_, view_mapped_, *groundtruth_);
        metrics.reentries = reentries.reentries;
        metrics.reentry_frames_to_fix_max = reentries.frames_to_fix_max;
        metrics.reentry_first_fix_error_max_mm = reentries.first_fix_error_max_mm;
      }
    }
    metrics.processing_fps = processing_s_ > 0.0 ? static_cast<double>(frames_) / processing_s_ : 0.0;
    std::sort(latency_ms_.begin(), latency_ms_.end());  // not empty: the estimate has a frame
    metrics.latency_p50_ms = dataset::Percentile(latency_ms_, 50.0);
    metrics.latency_p99_ms = dataset::Percentile(latency_ms_, 99.0);
    metrics.overlap_speed_limit_mps = OverlapSpeedLimit(info, estimate_, required_overlap);
    std::error_code ec;
    std::filesystem::create_directories(options.out, ec);
    const std::string heading = title + ": " + options.dataset.filename().string();
    CheckHeight(options, info, heading, &metrics);
    core::WriteFileAtomically(options.out / "fixes.csv", fixes_csv_);
    if (groundtruth_) {
      // Each row's position error against the truth at its time (empty where the truth has no
      // pose then), for the console's colouring of the drive by error.
      std::string errors = "#timestamp_ns,error_mm\n";
      for (const dataset::FrameReport& r : reports_) {
        errors += std::to_string(r.time.nanoseconds()) + ",";
        if (const auto truth = dataset::PoseAt(*groundtruth_, r.time, std::chrono::milliseconds(100))) {
          errors += fmt::format("{:.5f}", (r.world_from_vehicle.translation_mm() - truth->translation_mm()).norm());
        }
        errors += "\n";
      }
      core::WriteFileAtomically(options.out / "errors.csv", errors);
    }
    metrics = WriteReport(options.out, estimate_, groundtruth_, metrics, heading);
    WriteTruthFreePlots(options, info, heading);
    dataset::HtmlReportInputs page;
    page.title = heading;
    page.about = {{"dataset", options.dataset.string()},
                  {"map", options.map.empty() ? std::string("none") : options.map.string()},
                  {"mode", ToString(options.mode)},
                  {"ground truth", groundtruth_ ? "yes: the truth-based figures are filled" : "none"}};
    if (!options.config_file.empty()) {
      std::ifstream in(options.config_file);
      page.configuration = "# " + options.config_file.string() + "\n" +
                           std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
    dataset::WriteHtmlReport(options.out, page);
    return metrics;
  }

 private:
  // The camera's height the localizer held (its image scale times the calibrated height)
  // against the simulator's truth, when the dataset records both: metrics and height.png.
  void CheckHeight(const ReplayOptions& options, const dataset::DatasetInfo& info, const std::string& title,
                   dataset::Metrics* metrics) const {
    const std::filesystem::path file = options.dataset / dataset::kCameraTruthFile;
    const std::optional<double> calibrated_mm = CalibratedHeightMm(options.dataset, info);
    std::error_code ec;
    if (!calibrated_mm || !std::filesystem::exists(file, ec) || reports_.empty()) return;
    const double height_mm = *calibrated_mm;
    std::unordered_map<std::int64_t, double> truth;
    for (const dataset::CameraTruthSample& sample : dataset::ReadCameraTruth(file)) {
      truth[sample.time.nanoseconds()] = sample.truth.height_mm;
    }
    dataset::HeightSeries series;
    double sum_sq = 0.0;
    double max_error = 0.0;
    std::int64_t fixed = 0;
    for (const dataset::FrameReport& report : reports_) {
      const auto it = truth.find(report.time.nanoseconds());
      if (it == truth.end()) continue;
      series.seconds.push_back(core::ToSeconds(report.time - reports_.front().time));
      series.estimate_mm.push_back(report.scale * height_mm);
      series.truth_mm.push_back(it->second);
      if (!report.fixed) continue;
      const double error = series.estimate_mm.back() - it->second;
      sum_sq += error * error;
      max_error = std::max(max_error, std::abs(error));
      ++fixed;
    }
    if (fixed == 0) return;
    metrics->height_error_rms_mm = std::sqrt(sum_sq / static_cast<double>(fixed));
    metrics->height_error_max_mm = max_error;
    dataset::WriteHeightPlot(options.out, series, title, *metrics->height_error_rms_mm);
  }

  // The camera's repeatability at the frames with a fix, against the truth (the truth-free
  // figure's counterpart).
  void CameraRepeatability(const core::Pose2& vehicle_from_camera, dataset::Metrics* metrics) const {
    std::vector<Eigen::Vector2d> truth, error;
    for (const dataset::StampedPose& fixed : fixed_estimates_) {
      const auto at = dataset::PoseAt(*groundtruth_, fixed.time, std::chrono::milliseconds(100));
      if (!at) continue;
      truth.push_back((*at * vehicle_from_camera).translation_mm());
      error.push_back((fixed.world_from_vehicle * vehicle_from_camera).translation_mm() - truth.back());
    }
    std::vector<std::vector<Eigen::Vector2d>> errors;
    for (const std::vector<std::size_t>& visits : dataset::RevisitedPlaces(truth, dataset::EvaluationOptions{})) {
      errors.emplace_back();
      for (std::size_t i : visits) errors.back().push_back(error[i]);
    }
    if (const auto spread = dataset::SpreadAtPlaces(errors)) {
      metrics->repeatability_camera_mm = spread->rms_mm;
      metrics->repeatability_camera_places = spread->places;
    }
  }

  // map_state.png, map_quality.png and timelines.png: what needs no ground truth. The camera's
  // height is drawn where the image scale was estimated (it moved from 1) and the calibrated
  // height is known.
  void WriteTruthFreePlots(const ReplayOptions& options, const dataset::DatasetInfo& info, const std::string& heading) {
    const bool scale_held = std::any_of(reports_.begin(), reports_.end(),
                                        [](const dataset::FrameReport& r) { return r.scale != 1.0; });
    const double height_mm = scale_held ? CalibratedHeightMm(options.dataset, info).value_or(kNaN) : kNaN;
    std::vector<dataset::TimelineSample> timeline;
    timeline.reserve(reports_.size());
    for (std::size_t i = 0; i < reports_.size(); ++i) {
      const dataset::FrameReport& report = reports_[i];
      dataset::TimelineSample sample;
      sample.seconds = core::ToSeconds(report.time - reports_.front().time);
      sample.quality = report.fixed ? report.quality : kNaN;
      sample.sigma_mm = report.sigma_mm;
      sample.nis = report.nis.value_or(kNaN);
      sample.speed_mps = kNaN;
      if (i > 0) {
        const double dt_s = core::ToSeconds(report.time - reports_[i - 1].time);
        if (dt_s > 0.0) {
          sample.speed_mps =
              core::Distance(report.world_from_vehicle, reports_[i - 1].world_from_vehicle) / dt_s / 1000.0;
        }
      }
      sample.latency_ms = timeline_extras_[i].latency_ms;
      sample.calibration_first = timeline_extras_[i].calibration.x();
      sample.calibration_second = timeline_extras_[i].calibration.y();
      sample.height_mm = report.scale * height_mm;
      timeline.push_back(sample);
    }
    dataset::WriteMapPlots(options.out, reports_, floor_, heading);
    dataset::WriteTimelines(options.out, timeline, heading, info.vehicle.kind);
  }

  dataset::Metrics known_;
  std::optional<dataset::Trajectory> groundtruth_;
  const std::function<void(double)>& progress_;
  std::int64_t total_frames_;  ///< the recording's frames, for the progress
  dataset::Trajectory estimate_;
  std::vector<double> latency_ms_;
  double processing_s_ = 0.0;
  std::int64_t frames_ = 0;
  std::int64_t fixes_ = 0;
  std::string fixes_csv_ = dataset::FixesCsvHeader();
  std::vector<dataset::FrameReport> reports_;
  std::vector<double> view_mapped_;
  std::vector<Eigen::Vector3d> innovations_;
  // Per report: what the timelines need beyond its row of fixes.csv.
  struct TimelineExtras {
    double latency_ms;
    Eigen::Vector2d calibration;
  };
  std::vector<TimelineExtras> timeline_extras_;
  double last_latency_ms_ = kNaN;
  std::optional<dataset::StampedPose> last_estimate_;
  dataset::Trajectory fixed_estimates_;
  dataset::FloorPicture floor_;
};

// The encoder time stamps' uncertainty a live recording noted (its PLC's timing error), else
// `otherwise`.
double EncoderTimingSigmaOf(const dataset::DatasetInfo& info, double otherwise) {
  const auto noted = info.provenance.find("encoder_timing_sigma_ms");
  if (noted == info.provenance.end()) return otherwise;
  try {
    return std::stod(noted->second);
  } catch (const std::exception&) {
    core::ThrowInvalidInput("dataset.yaml: provenance.encoder_timing_sigma_ms: '" + noted->second + "' is not a number");
  }
}

// Records what automatic mapping did: the figures, and the painted frames' vehicle poses
// (mapped.tum) with their error against the truth.
void RecordExtension(const MapKeeper& keeper, const MapKeepingSummary& kept,
                     const std::optional<dataset::Trajectory>& groundtruth, const dataset::DatasetInfo& info,
                     const std::filesystem::path& out, dataset::Metrics* known) {
  const mapping::ExtensionSummary& s = kept.extension;
  known->map_extension_overspeed_frames = kept.overspeed_frames;
  known->map_extension_speed_max_mps = kept.mapping_speed_max_mps;
  known->map_extension_segments = s.segments;
  known->map_extension_closed = s.closed;
  known->map_extension_keyframes = s.keyframes;
  known->map_extension_tiles = s.tiles_written;
  known->map_extension_unanchored = s.unanchored;
  known->map_extension_bridged = s.bridged;
  known->map_extension_closure_max_mm = s.closure_max_mm;
  dataset::Trajectory painted;
  double sum_sq = 0.0, worst = 0.0;
  std::int64_t compared = 0;
  for (const auto& [time, world_from_camera] : keeper.painted()) {
    painted.push_back({time, world_from_camera * info.camera.vehicle_from_camera.Inverse()});
    if (!groundtruth) continue;
    const auto truth = dataset::PoseAt(*groundtruth, time, std::chrono::milliseconds(100));
    if (!truth) continue;
    const double error = (painted.back().world_from_vehicle.translation_mm() - truth->translation_mm()).norm();
    sum_sq += error * error;
    worst = std::max(worst, error);
    ++compared;
  }
  if (compared > 0) {
    known->map_extension_pose_rms_mm = std::sqrt(sum_sq / static_cast<double>(compared));
    known->map_extension_pose_max_mm = worst;
  }
  std::error_code ec;
  std::filesystem::create_directories(out, ec);
  dataset::WriteTum(out / "mapped.tum", painted);
}

// Records what automatic map updates did; with the truth, how far off the frames they were
// painted from were.
void RecordUpdates(const mapping::UpdateSummary& s, const std::optional<dataset::Trajectory>& groundtruth,
                   const dataset::DatasetInfo& info, dataset::Metrics* known) {
  dataset::Metrics::MapUpdateFigures figures;
  figures.updates = s.updates;
  figures.cells = s.cells_updated;
  figures.tiles = s.tiles_written;
  figures.pending_cells = s.cells_pending;
  figures.compared = s.compared;
  figures.mostly_changed = s.mostly_changed;
  figures.repeating = s.repeating;
  if (groundtruth) {
    double worst = 0.0;
    for (const auto& [time, world_from_camera] : s.painted) {
      const auto truth = dataset::PoseAt(*groundtruth, time, std::chrono::milliseconds(100));
      if (!truth) continue;
      const core::Pose2 vehicle = world_from_camera * info.camera.vehicle_from_camera.Inverse();
      worst = std::max(worst, (vehicle.translation_mm() - truth->translation_mm()).norm());
    }
    if (!s.painted.empty()) figures.pose_max_mm = worst;
  }
  known->map_update = figures;
}

// Dead reckoning: integrate the wheel encoders from the starting pose, and report the pose
// at every frame's time. This is the baseline the mosaic fix removes the drift from.
ReplaySummary ReplayDeadReckoning(const ReplayOptions& options, const std::function<void(double)>& progress) {
  const dataset::DatasetReader reader(options.dataset);
  const dataset::DatasetInfo& info = reader.info();
  const std::optional<dataset::Trajectory> groundtruth = TruthInMapFrame(reader, options);
  ReplaySummary summary;
  summary.report = options.out;
  // The start is known (as a localizer would be told at installation): the first ground
  // truth pose, or the origin.
  const dataset::Trajectory integrated =
      WheelTrajectory(reader,
                      StartPose(groundtruth, info, groundtruth ? groundtruth->front().time : core::Timestamp()),
                      &summary.encoder_samples_rejected);

  ReplayRecord record(reader, groundtruth, progress);
  auto stream = reader.Frames();
  while (true) {
    const auto frame_start = std::chrono::steady_clock::now();
    const auto frame = stream.Next(/*decode=*/false);
    if (!frame) break;
    const auto pose = dataset::PoseAt(integrated, frame->time, std::chrono::milliseconds(100));
    record.Frame(frame->time, pose,
                 std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - frame_start).count());
    if (pose) {
      dataset::FrameReport report;
      report.time = frame->time;
      report.world_from_vehicle = *pose;
      report.reason = "dead-reckoning";
      record.Report(report);
    }
  }
  // Dead reckoning makes no visual fix: every row of fixes.csv has status 0 (none).
  summary.metrics = record.Finish(options, info, options.settings.required_overlap, std::nullopt, "dead reckoning");
  return summary;
}

// The localizer over the map: odometry drives the filter, every frame is registered against
// the map and fused. Frames are processed after the first encoder sample that follows them,
// so each fix is late, as on a vehicle, and is applied at its own time.
ReplaySummary ReplayMosaic(const ReplayOptions& options, const std::function<void(double)>& progress) {
  const LocalizationSettings& settings = options.settings;
  const dataset::DatasetReader reader(options.dataset);
  const dataset::DatasetInfo& info = reader.info();
  const std::optional<dataset::Trajectory> groundtruth = TruthInMapFrame(reader, options);

  // With prefetching the map's tiles along the predicted path are loaded on threads of their
  // own, as `run` loads them, and the frames' processing times are the tracking thread's. The
  // estimates are the same either way: only where a tile is loaded changes.
  if (options.prefetch && !(settings.prefetch_horizon_s > 0.0)) {
    core::ThrowInvalidInput("replay --prefetch: map.prefetch_horizon_s of the configuration is 0");
  }
  MapSessionOptions map_options;
  map_options.cache_budget_bytes = settings.cache_budget_mib << 20;
  map_options.camera_mm_per_px = info.camera.mm_per_px;
  if (options.prefetch) map_options.prefetch = PrefetchOptionsFor(settings, info.camera);
  map_options.writable = options.mapping;
  MapSession map(options.map, map_options);
  if (map.created()) core::Log().info("replay: {} created empty, to be mapped as the drive goes", options.map.string());

  const camera::IdealCamera camera = CameraOf(info);
  const localizer::LocalizerOptions localizer_options =
      LocalizerOptionsFor(settings.localizer, info.camera, info.vehicle,
                          EncoderTimingSigmaOf(info, settings.localizer.odometry_timing_sigma_ms));
  localizer::Localizer localizer(camera, localizer_options, map.reference(), &map.places());
  std::optional<MapKeeper> keeper;
  if (options.mapping) {
    keeper.emplace(map, camera, localizer_options.tracker, settings, info.camera.vehicle_from_camera,
                   /*background=*/false);
  }

  auto encoders = reader.Encoders();
  std::optional<dataset::EncoderSample> pending = encoders.Next();
  if (!pending) core::ThrowInvalidInput(options.dataset.string() + ": no encoder samples");
  core::Pose2 start = StartPose(groundtruth, info, pending->time);
  // A wrong start (a kidnapped vehicle): the localizer must find where it really is.
  if (options.start_offset) start = start * *options.start_offset;
  if (options.unknown_start) {
    localizer.InitializeUnknown(pending->time);
    if (!map.places().usable()) core::Log().warn("replay: the start is unknown, and {}", map.places().problem());
  } else {
    // A map with no floor yet (automatic mapping from scratch) is where the vehicle starts: the
    // start is its origin, exact by definition.
    const bool empty = options.mapping && map.store().Count(0) == 0;
    localizer.Initialize(pending->time, start,
                         empty ? StartCovariance(1e-3, 1e-4) : StartCovariance(settings.start_sigma_mm, settings.start_sigma_deg));
    if (empty) core::Log().info("replay: the map has no floor yet: the start is its origin");
  }
  if (options.relocalize) localizer.RequestRelocalization();
  std::optional<core::Timestamp> first_frame;
  std::int64_t frame_index = 0;
  std::optional<std::int64_t> kidnapped_at;
  ReplaySummary summary;
  summary.report = options.out;
  core::Timestamp last_fed = pending->time;
  const auto feed = [&] {
    last_fed = pending->time;
    if (!localizer.AddEncoders(pending->time, pending->counts)) {
      ++summary.encoder_samples_rejected;
    }
    pending = encoders.Next();
  };

  ReplayRecord record(reader, groundtruth, progress);
  auto stream = reader.Frames();
  while (const auto frame = stream.Next()) {
    while (pending && pending->time <= frame->time) feed();
    if (pending) feed();  // one sample past the frame: the fix arrives late
    if (!first_frame) first_frame = frame->time;
    if (options.until_s && core::ToSeconds(frame->time - *first_frame) > *options.until_s) break;
    if (options.kidnap_at_s && !kidnapped_at && core::ToSeconds(frame->time - *first_frame) >= *options.kidnap_at_s) {
      // Carried away unseen: the estimate stays confident where the vehicle no longer is.
      // The filter restarts at the newest odometry it has taken, so that none is lost.
      kidnapped_at = frame_index;
      localizer.SetPose(last_fed, localizer.PoseAt(last_fed) * options.kidnap_offset,
                        StartCovariance(settings.start_sigma_mm, settings.start_sigma_deg));
      if (options.kidnap_told) localizer.RequestRelocalization();
      core::Log().info("replay: kidnap at frame {}", frame_index);
    }
    const auto started = std::chrono::steady_clock::now();
    const localizer::FrameOutcome outcome = localizer.ProcessFrame(frame->time, frame->image);
    if (keeper) keeper->Frame(frame->time, frame->image, outcome, !localizer.pose_unknown());
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - started).count();
    // While the pose is unknown there is no estimate to evaluate.
    record.Frame(frame->time,
                 localizer.pose_unknown() ? std::nullopt : std::optional<core::Pose2>(outcome.world_from_vehicle), ms);
    if (outcome.fixed && !record.known().frames_to_first_fix) {
      record.known().frames_to_first_fix = frame_index;
      record.known().first_fix_s = core::ToSeconds(frame->time - *first_frame);
    }
    if (outcome.fixed && kidnapped_at && !record.known().kidnap_frames_to_fix) {
      record.known().kidnap_frames_to_fix = frame_index - *kidnapped_at;
    }
    ++frame_index;
    if (map.prefetcher() && localizer.initialized()) {
      PredictTiles(*map.prefetcher(), localizer.Latest(), info.camera.vehicle_from_camera);
    }
    std::optional<double> view_mapped;
    if (groundtruth) {
      const auto truth = dataset::PoseAt(*groundtruth, frame->time, std::chrono::milliseconds(100));
      view_mapped = truth ? localizer::MapCoverage(map.reference(), camera,
                                                   *truth * info.camera.vehicle_from_camera, 0.0, 2)
                          : 0.0;
    }
    FrameExtras extras;
    if (outcome.nis) extras.normalized_innovation = outcome.normalized_innovation;
    if (localizer.initialized()) extras.calibration = CalibrationErrorsShown(localizer.wheel_scale_error(), info.vehicle.kind).values;
    record.Report(FrameReportOf(frame->time, outcome), view_mapped, extras);
    if (!outcome.fixed) {
      const core::Pose2& f = outcome.fix_world_from_vehicle;
      core::Log().debug("frame {}: no fix: {} (tracker: {:.4f}, {:.4f}, {:.6f}; estimate {:.4f}, {:.4f}, {:.6f})",
                        frame->time.nanoseconds(), outcome.reason, f.x_mm(), f.y_mm(), f.yaw_rad(),
                        outcome.world_from_vehicle.x_mm(), outcome.world_from_vehicle.y_mm(),
                        outcome.world_from_vehicle.yaw_rad());
    }
  }
  if (summary.encoder_samples_rejected > 0) {
    core::Log().warn("{} encoder samples rejected", summary.encoder_samples_rejected);
  }
  if (keeper) {
    const MapKeepingSummary kept = keeper->Finish();
    summary.map_keeping_failure = kept.failure;
    RecordExtension(*keeper, kept, groundtruth, info, options.out, &record.known());
    if (settings.map_update.enabled) RecordUpdates(kept.updates, groundtruth, info, &record.known());
  }
  summary.tiles_loaded = map.cache().stats().misses;
  summary.relocalizations = localizer.relocalizations();
  summary.reanchorings = localizer.reanchorings();
  summary.wheel_scale_error = localizer.wheel_scale_error();
  summary.wheel_scale_sigma = localizer.wheel_scale_sigma();
  core::Log().info("map cache: {} tiles loaded, {} relocalizations, {} re-anchorings", summary.tiles_loaded,
                   summary.relocalizations, summary.reanchorings);
  const Eigen::Vector2d learnt = CalibrationErrorsShown(summary.wheel_scale_error, info.vehicle.kind).values;
  const Eigen::Vector2d sigma = CalibrationErrorsShown(summary.wheel_scale_sigma, info.vehicle.kind).values;
  if (info.vehicle.kind == core::DriveKind::kTricycle) {
    record.known().drive_wheel_scale_percent = learnt.x();
    record.known().steering_offset_error_deg = learnt.y();
    core::Log().info("calibration errors learnt: drive wheel scale {:+.3f} % (sigma {:.3f}), steering offset {:+.4f} deg "
                     "(sigma {:.4f})", learnt.x(), sigma.x(), learnt.y(), sigma.y());
  } else if (info.vehicle.kind == core::DriveKind::kMecanum) {
    record.known().wheel_scale_percent = learnt.x();
    record.known().lateral_scale_percent = learnt.y();
    core::Log().info("calibration errors learnt: wheel scale {:+.3f} % (sigma {:.3f}), sideways scale {:+.3f} % "
                     "(sigma {:.3f})", learnt.x(), sigma.x(), learnt.y(), sigma.y());
  } else {
    record.known().wheel_scale_left_percent = learnt.x();
    record.known().wheel_scale_right_percent = learnt.y();
    core::Log().info("wheel scale errors learnt: left {:+.3f} % (sigma {:.3f}), right {:+.3f} % (sigma {:.3f})",
                     learnt.x(), sigma.x(), learnt.y(), sigma.y());
  }
  if (options.revisit_places > 0) {
    // Repeatability from the recording alone: revisited places registered frame to frame.
    RevisitOptions revisit_options;
    revisit_options.max_places = options.revisit_places;
    const RevisitFigures revisits = MeasureRevisits(options.dataset, record.fixed_estimates(), camera,
                                                    localizer_options.tracker, info.camera.vehicle_from_camera,
                                                    revisit_options);
    record.known().revisit_repeatability_mm = revisits.repeatability_mm;
    record.known().revisit_places = revisits.places;
    record.known().revisit_visits = revisits.visits;
    record.known().revisit_failures = revisits.failures;
  }
  record.SetFloor(FloorPictureOf(map, record.reports()));
  summary.metrics = record.Finish(options, info, settings.required_overlap, localizer.lock().losses(),
                                  "mosaic localization", localizer.relocalizations(), localizer.reanchorings());
  return summary;
}

// Frame-to-frame visual odometry with the tracker, no map: each frame is registered against
// the previous one around the wheel odometry's motion, and the motions chained. Where frames
// stop overlapping (beyond the overlap speed limit) or registration fails, the wheel motion
// is used. The comparison that shows what a prior map buys.
ReplaySummary ReplayVisualOdometry(const ReplayOptions& options, const std::function<void(double)>& progress) {
  const dataset::DatasetReader reader(options.dataset);
  const dataset::DatasetInfo& info = reader.info();
  const std::optional<dataset::Trajectory> groundtruth = TruthInMapFrame(reader, options);
  const core::Pose2 vehicle_from_camera = info.camera.vehicle_from_camera;
  ReplaySummary summary;
  summary.report = options.out;
  // The wheels give each frame pair's predicted motion (only differences are used).
  const dataset::Trajectory wheel =
      WheelTrajectory(reader, core::Pose2::Identity(), &summary.encoder_samples_rejected);

  const camera::IdealCamera camera = CameraOf(info);
  const tracking::Tracker tracker(camera, options.settings.localizer.tracker);
  ReplayRecord record(reader, groundtruth, progress);
  cv::Mat previous;
  core::Timestamp previous_time;
  core::Pose2 pose;
  auto stream = reader.Frames();
  while (auto frame = stream.Next()) {
    const auto wheel_pose = dataset::PoseAt(wheel, frame->time, std::chrono::milliseconds(100));
    if (!wheel_pose) continue;
    const auto started = std::chrono::steady_clock::now();
    bool registered = false;
    double quality = 0.0;
    if (previous.empty()) {
      pose = StartPose(groundtruth, info, frame->time);
    } else {
      const core::Pose2 wheel_motion =
          Between(*dataset::PoseAt(wheel, previous_time, std::chrono::milliseconds(100)), *wheel_pose);
      // The wheels' motion as the prior, uncertain by 2 mm + 5 % of its length and 0.5 deg.
      const double sigma_mm = 2.0 + 0.05 * wheel_motion.translation_mm().norm();
      const double sigma_rad = 0.5 * std::numbers::pi / 180.0;
      const Eigen::Matrix3d prior =
          Eigen::Vector3d(sigma_mm * sigma_mm, sigma_mm * sigma_mm, sigma_rad * sigma_rad).asDiagonal();
      const core::Pose2 camera_motion = vehicle_from_camera.Inverse() * wheel_motion * vehicle_from_camera;
      const tracking::TrackResult r = tracking::RegisterFrames(tracker, previous, frame->image, camera_motion, prior);
      core::Pose2 motion = wheel_motion;
      if (r.ok()) {
        motion = vehicle_from_camera * r.world_from_camera * vehicle_from_camera.Inverse();
        registered = true;
        quality = r.mean_zncc;
      } else {
        core::Log().debug("frame {}: not registered to the previous one: {}", frame->time.nanoseconds(), r.reason);
      }
      pose = pose * motion;
    }
    record.Frame(frame->time, pose,
                 std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - started).count());
    // A registered frame is a relative fix: the chained pose, status 1; else the wheels'
    // motion carried it, status 2.
    dataset::FrameReport report;
    report.time = frame->time;
    report.world_from_vehicle = pose;
    report.fixed = registered;
    report.status = registered ? 1 : 2;
    report.quality = quality;
    report.reason = registered || previous.empty() ? "" : "not-registered";
    record.Report(report);
    previous = frame->image;
    previous_time = frame->time;
  }
  summary.metrics = record.Finish(options, info, options.settings.required_overlap, std::nullopt, "visual odometry");
  return summary;
}

}  // namespace

const char* ToString(ReplayMode mode) {
  switch (mode) {
    case ReplayMode::kMosaic: return "mosaic";
    case ReplayMode::kDeadReckoning: return "dead-reckoning";
    case ReplayMode::kVisualOdometry: return "visual-odometry";
  }
  return "unknown";
}

std::optional<ReplayMode> ParseReplayMode(std::string_view name) {
  for (const ReplayMode mode : kReplayModes) {
    if (name == ToString(mode)) return mode;
  }
  return std::nullopt;
}

ReplaySummary Replay(const ReplayOptions& options, const std::function<void(double)>& progress) {
  switch (options.mode) {
    case ReplayMode::kDeadReckoning: return ReplayDeadReckoning(options, progress);
    case ReplayMode::kVisualOdometry: return ReplayVisualOdometry(options, progress);
    case ReplayMode::kMosaic: break;
  }
  if (options.map.empty()) core::ThrowInvalidInput("replay: the mosaic mode needs a map");
  std::error_code ec;
  if (!options.mapping && !std::filesystem::is_regular_file(options.map, ec)) {
    core::ThrowInvalidInput("replay: --map: " + options.map.string() + " does not exist (give --mapping to create it)");
  }
  return ReplayMosaic(options, progress);
}

}  // namespace mosaicloc::runtime
