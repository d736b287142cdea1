#include <algorithm>
#include <chrono>

#include <fmt/format.h>
#include <cmath>
#include <numbers>
#include <optional>
#include <cstdio>
#include <vector>

#include "commands.hpp"
#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/file.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/dataset/evaluation.hpp"
#include "mosaicloc/dataset/fixes.hpp"
#include "mosaicloc/estimation/odometry.hpp"
#include "localizer_config.hpp"
#include "mosaicloc/dataset/trajectory.hpp"
#include "mosaicloc/localizer/localizer.hpp"
#include "mosaicloc/localizer/speed_limits.hpp"
#include "mosaicloc/mosaic/prefetcher.hpp"
#include "mosaicloc/mosaic/renderer.hpp"
#include "mosaicloc/mosaic/tile_cache.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"
#include "mosaicloc/tracking/reference.hpp"
#include "mosaicloc/tracking/tracker.hpp"
#include "progress.hpp"
#include "report.hpp"

namespace mosaicloc::app {
namespace {

// The dataset's vehicle geometry over `options` (the configuration's error model).
estimation::DiffDriveOptions OdometryFor(const dataset::DatasetInfo& info,
                                         estimation::DiffDriveOptions options = estimation::DiffDriveOptions{}) {
  options.left_wheel_radius_mm = info.vehicle.left_wheel_radius_mm;
  options.right_wheel_radius_mm = info.vehicle.right_wheel_radius_mm;
  options.track_width_mm = info.vehicle.track_width_mm;
  options.ticks_per_revolution = info.vehicle.ticks_per_revolution;
  return options;
}

camera::IdealCamera CameraOf(const dataset::DatasetInfo& info) {
  return camera::IdealCamera(
      camera::IdealCameraOptions{info.camera.width_px, info.camera.height_px, info.camera.mm_per_px});
}

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

struct ReplayArgs {
  std::filesystem::path dataset;
  std::filesystem::path map;
  std::filesystem::path out;
  std::filesystem::path config;
  std::string mode;  // empty: mosaic with --map, else an error
  std::optional<double> required_overlap;
  std::vector<double> start_offset;  // dx_mm, dy_mm, dyaw_deg in the start's vehicle frame
  bool prefetch = false;             // load tiles ahead on the prefetcher's threads, as `run` does
  bool relocalize = false;           // the start is not to be trusted: relocalize without it
};


// Dead reckoning: integrate the wheel encoders from the starting pose, and report the pose
// at every frame's time. This is the baseline the mosaic fix removes the drift from.
// What a replay mode records frame by frame, and the report made of it.
class ReplayRecord {
 public:
  ReplayRecord(std::optional<dataset::Trajectory> groundtruth, bool quiet)
      : groundtruth_(std::move(groundtruth)), progress_("replay", quiet) {}

  const std::optional<dataset::Trajectory>& groundtruth() const { return groundtruth_; }

  /// One frame: the estimate at its time (if any) and the processing time, ms.
  void Frame(core::Timestamp time, const std::optional<core::Pose2>& world_from_vehicle, double ms) {
    ++frames_;
    if (world_from_vehicle) estimate_.push_back({time, *world_from_vehicle});
    latency_ms_.push_back(ms);
    processing_s_ += ms * 1e-3;
    if (frames_ % 16 == 0 && groundtruth_) {
      const auto span = groundtruth_->back().time - groundtruth_->front().time;
      progress_.Update(std::clamp(static_cast<double>((time - groundtruth_->front().time).count()) /
                                      static_cast<double>(span.count() + 1),
                                  0.0, 1.0));
    }
  }

  /// What the localizer reported for a frame (a row of fixes.csv); `view_mapped`: the share
  /// of the true view the map covers there (mosaic mode with ground truth), for the returns.
  void Report(const dataset::FrameReport& report, std::optional<double> view_mapped = std::nullopt) {
    if (report.fixed) ++fixes_;
    fixes_csv_ += dataset::FixesCsvRow(report);
    reports_.push_back(report);
    if (view_mapped) view_mapped_.push_back(*view_mapped);
  }

  /// Writes fixes.csv, metrics.json, estimate.tum and the plots, and prints the metrics.
  void Finish(const ReplayArgs& args, const GlobalOptions& global, const dataset::DatasetInfo& info,
              double required_overlap, std::optional<std::int64_t> lock_losses, const std::string& title,
              std::optional<std::int64_t> relocalizations = std::nullopt) {
    progress_.Finish();
    if (estimate_.empty()) {
      core::ThrowInvalidInput(args.dataset.string() + ": no frame falls within the encoder samples");
    }
    dataset::Metrics metrics;
    metrics.frames = frames_;
    metrics.fixes = fixes_;
    metrics.fix_rate = static_cast<double>(fixes_) / static_cast<double>(frames_);
    metrics.lock_losses = lock_losses;
    metrics.relocalizations = relocalizations;
    if (groundtruth_) {
      // Every fix checked against the truth: a lock that never broke proves nothing if it held
      // onto the wrong place.
      const dataset::FixCheck check = dataset::CheckFixes(reports_, *groundtruth_);
      metrics.wrong_fixes = check.wrong_fixes;
      metrics.max_wrong_fix_mm = check.max_wrong_fix_mm.value_or(0.0);
      metrics.off_map_frames = check.off_map_frames;
      metrics.off_map_max_error_mm = check.off_map_max_error_mm;
      if (view_mapped_.size() == reports_.size()) {
        const dataset::ReentryCheck reentries =
            dataset::CheckReentries(reports_, view_mapped_, *groundtruth_);
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
    std::filesystem::create_directories(args.out, ec);
    core::WriteFileAtomically(args.out / "fixes.csv", fixes_csv_);
    const dataset::Metrics written =
        WriteReport(args.out, estimate_, groundtruth_, metrics, title + ": " + args.dataset.filename().string());
    PrintMetrics(args.out, written, global.json);
  }

 private:
  std::optional<dataset::Trajectory> groundtruth_;
  ProgressBar progress_;
  dataset::Trajectory estimate_;
  std::vector<double> latency_ms_;
  double processing_s_ = 0.0;
  std::int64_t frames_ = 0;
  std::int64_t fixes_ = 0;
  std::string fixes_csv_ = dataset::FixesCsvHeader();
  std::vector<dataset::FrameReport> reports_;
  std::vector<double> view_mapped_;
};

// Where the run starts (as a localizer is told at installation): the ground truth at `time`,
// else its first pose; without ground truth, the start pose a live recording noted in its
// provenance ("x_mm,y_mm,yaw_deg"), else the origin.
core::Pose2 StartPose(const std::optional<dataset::Trajectory>& groundtruth, const dataset::DatasetInfo& info,
                      core::Timestamp time) {
  if (groundtruth) {
    return dataset::PoseAt(*groundtruth, time, std::chrono::seconds(1))
        .value_or(groundtruth->front().world_from_vehicle);
  }
  const auto noted = info.provenance.find("start_pose");
  if (noted == info.provenance.end()) return core::Pose2::Identity();
  double x = 0.0, y = 0.0, yaw_deg = 0.0;
  if (std::sscanf(noted->second.c_str(), "%lf,%lf,%lf", &x, &y, &yaw_deg) != 3) {
    core::ThrowInvalidInput("dataset.yaml: provenance.start_pose: '" + noted->second +
                            "' is not x_mm,y_mm,yaw_deg");
  }
  return core::Pose2(x, y, yaw_deg * std::numbers::pi / 180.0);
}

std::optional<dataset::Trajectory> GroundTruthOf(const dataset::DatasetReader& reader) {
  if (!reader.HasGroundTruth()) return std::nullopt;
  return reader.GroundTruth();
}

LocalizerConfig ConfigOf(const ReplayArgs& args) {
  LocalizerConfig config = args.config.empty() ? LocalizerConfig{} : LoadLocalizerConfig(args.config);
  if (args.required_overlap) config.required_overlap = *args.required_overlap;
  return config;
}

// The wheel encoders integrated from `start` (dead reckoning), one pose per accepted sample.
// Rejected samples are logged and skipped.
dataset::Trajectory WheelTrajectory(const ReplayArgs& args, const dataset::DatasetReader& reader,
                                    const core::Pose2& start) {
  estimation::DiffDriveOdometry odometry(OdometryFor(reader.info()), start);
  dataset::Trajectory integrated;
  std::int64_t rejected = 0;
  auto encoders = reader.Encoders();
  while (const auto sample = encoders.Next()) {
    const auto increment = odometry.Update(sample->time, sample->left_ticks, sample->right_ticks);
    if (!increment) {
      ++rejected;
      core::Log().warn("{}: encoder sample at {} ns skipped: {}", args.dataset.string(), sample->time.nanoseconds(),
                       estimation::ToString(increment.error()));
      continue;
    }
    integrated.push_back({sample->time, odometry.world_from_vehicle()});
  }
  if (integrated.empty()) core::ThrowInvalidInput(args.dataset.string() + ": no encoder samples");
  if (rejected > 0) core::Log().warn("{} encoder samples rejected", rejected);
  return integrated;
}

void RunDeadReckoning(const ReplayArgs& args, const GlobalOptions& global) {
  const dataset::DatasetReader reader(args.dataset);
  const dataset::DatasetInfo& info = reader.info();
  const std::optional<dataset::Trajectory> groundtruth = GroundTruthOf(reader);
  // The start is known (as a localizer would be told at installation): the first ground
  // truth pose, or the origin.
  const dataset::Trajectory integrated =
      WheelTrajectory(args, reader, StartPose(groundtruth, info, groundtruth ? groundtruth->front().time : core::Timestamp()));

  ReplayRecord record(groundtruth, global.quiet);
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
  record.Finish(args, global, info, args.required_overlap.value_or(0.5), std::nullopt, "dead reckoning");
}

// The localizer over the map: odometry drives the filter, every frame is registered against
// the map and fused. Frames are processed after the first encoder sample that follows them,
// so each fix is late, as on a vehicle, and is applied at its own time.
void RunMosaic(const ReplayArgs& args, const GlobalOptions& global) {
  LocalizerConfig config = ConfigOf(args);
  const dataset::DatasetReader reader(args.dataset);
  const dataset::DatasetInfo& info = reader.info();
  const std::optional<dataset::Trajectory> groundtruth = GroundTruthOf(reader);

  const std::unique_ptr<mosaic::TileStore> store = mosaic::TileStore::Open(args.map, /*writable=*/false);
  mosaic::TileCache cache(*store, config.cache_budget_mib << 20);
  const mosaic::MapRenderer renderer(cache);
  const tracking::MapReference reference(renderer, 0);
  if (std::abs(store->grid().mm_per_px - info.camera.mm_per_px) > 1e-9) {
    core::ThrowInvalidInput(args.map.string() + ": map resolution " + std::to_string(store->grid().mm_per_px) +
                            " mm/px differs from the dataset's camera (" + std::to_string(info.camera.mm_per_px) +
                            " mm/px)");
  }

  const camera::IdealCamera camera = CameraOf(info);
  // With --prefetch the map's tiles along the predicted path are loaded on threads of their
  // own, as `run` loads them, and the frames' processing times are the tracking thread's.
  // The estimates are the same either way: only where a tile is loaded changes.
  std::unique_ptr<mosaic::TilePrefetcher> prefetcher;  // after the cache: stops before it goes
  if (args.prefetch) {
    if (!(config.prefetch_horizon_s > 0.0)) {
      core::ThrowInvalidInput("replay --prefetch: map.prefetch_horizon_s of the configuration is 0");
    }
    prefetcher = std::make_unique<mosaic::TilePrefetcher>(
        cache, PrefetchOptionsFor(config, info.camera.width_px, info.camera.height_px, info.camera.mm_per_px));
  }
  config.localizer.odometry = OdometryFor(info, config.localizer.odometry);
  config.localizer.vehicle_from_camera = info.camera.vehicle_from_camera;
  // A live recording's encoder time stamps carry the PLC's timing error; the run noted it.
  if (const auto noted = info.provenance.find("encoder_timing_sigma_ms"); noted != info.provenance.end()) {
    try {
      config.localizer.odometry_timing_sigma_ms = std::stod(noted->second);
    } catch (const std::exception&) {
      core::ThrowInvalidInput("dataset.yaml: provenance.encoder_timing_sigma_ms: '" + noted->second + "' is not a number");
    }
  }
  localizer::Localizer localizer(camera, config.localizer, reference);

  auto encoders = reader.Encoders();
  std::optional<dataset::EncoderSample> pending = encoders.Next();
  if (!pending) core::ThrowInvalidInput(args.dataset.string() + ": no encoder samples");
  core::Pose2 start = StartPose(groundtruth, info, pending->time);
  if (!args.start_offset.empty()) {
    // A wrong start (a kidnapped vehicle): the localizer must find where it really is.
    start = start * core::Pose2(args.start_offset[0], args.start_offset[1],
                                args.start_offset[2] * std::numbers::pi / 180.0);
  }
  const double start_sigma_rad = config.start_sigma_deg * std::numbers::pi / 180.0;
  localizer.Initialize(pending->time, start,
                       Eigen::Vector3d(config.start_sigma_mm * config.start_sigma_mm,
                                       config.start_sigma_mm * config.start_sigma_mm, start_sigma_rad * start_sigma_rad)
                           .asDiagonal());
  if (args.relocalize) localizer.RequestRelocalization();
  std::int64_t rejected = 0;
  const auto feed = [&] {
    if (!localizer.AddEncoders(pending->time, pending->left_ticks, pending->right_ticks)) ++rejected;
    pending = encoders.Next();
  };

  ReplayRecord record(groundtruth, global.quiet);
  auto stream = reader.Frames();
  while (const auto frame = stream.Next()) {
    while (pending && pending->time <= frame->time) feed();
    if (pending) feed();  // one sample past the frame: the fix arrives late
    const auto started = std::chrono::steady_clock::now();
    const localizer::FrameOutcome outcome = localizer.ProcessFrame(frame->time, frame->image);
    record.Frame(frame->time, outcome.world_from_vehicle,
                 std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - started).count());
    if (prefetcher && localizer.initialized()) {
      PredictTiles(*prefetcher, localizer.Latest(), info.camera.vehicle_from_camera);
    }
    std::optional<double> view_mapped;
    if (groundtruth) {
      const auto truth = dataset::PoseAt(*groundtruth, frame->time, std::chrono::milliseconds(100));
      view_mapped = truth ? localizer::MapCoverage(reference, camera, *truth * info.camera.vehicle_from_camera, 0.0, 2)
                          : 0.0;
    }
    record.Report(FrameReportOf(frame->time, outcome), view_mapped);
    if (!outcome.fixed) {
      const core::Pose2& f = outcome.fix_world_from_vehicle;
      core::Log().debug("frame {}: no fix: {} (tracker: {:.4f}, {:.4f}, {:.6f}; estimate {:.4f}, {:.4f}, {:.6f})",
                        frame->time.nanoseconds(), outcome.reason, f.x_mm(), f.y_mm(), f.yaw_rad(),
                        outcome.world_from_vehicle.x_mm(), outcome.world_from_vehicle.y_mm(),
                        outcome.world_from_vehicle.yaw_rad());
    }
  }
  if (rejected > 0) core::Log().warn("{} encoder samples rejected", rejected);
  const mosaic::TileCacheStats stats = cache.stats();
  core::Log().info("map cache: {} tiles loaded, {} relocalizations", stats.misses, localizer.relocalizations());
  const Eigen::Vector2d scale = 100.0 * localizer.wheel_scale_error(), sigma = 100.0 * localizer.wheel_scale_sigma();
  core::Log().info("wheel scale errors learnt: left {:+.3f} % (sigma {:.3f}), right {:+.3f} % (sigma {:.3f})",
                   scale.x(), sigma.x(), scale.y(), sigma.y());
  record.Finish(args, global, info, config.required_overlap, localizer.lock().losses(), "mosaic localization",
                localizer.relocalizations());
}

// Frame-to-frame visual odometry with the tracker, no map: each frame is registered against
// the previous one around the wheel odometry's motion, and the motions chained. Where frames
// stop overlapping (beyond the overlap speed limit) or registration fails, the wheel motion
// is used. The comparison that shows what a prior map buys.
void RunVisualOdometry(const ReplayArgs& args, const GlobalOptions& global) {
  const LocalizerConfig config = ConfigOf(args);
  const dataset::DatasetReader reader(args.dataset);
  const dataset::DatasetInfo& info = reader.info();
  const std::optional<dataset::Trajectory> groundtruth = GroundTruthOf(reader);
  const core::Pose2 vehicle_from_camera = info.camera.vehicle_from_camera;
  // The wheels give each frame pair's predicted motion (only differences are used).
  const dataset::Trajectory wheel = WheelTrajectory(args, reader, core::Pose2::Identity());

  const camera::IdealCamera camera = CameraOf(info);
  const tracking::Tracker tracker(camera, config.localizer.tracker);
  ReplayRecord record(groundtruth, global.quiet);
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
  record.Finish(args, global, info, config.required_overlap, std::nullopt, "visual odometry");
}

}  // namespace

Action AddReplayCommand(CLI::App& app, const GlobalOptions& global) {
  auto args = std::make_shared<ReplayArgs>();
  CLI::App* command = app.add_subcommand("replay", "Localize a recorded or simulated dataset and write a report");
  command->add_option("--dataset", args->dataset, "Dataset directory")->required();
  command->add_option("--map", args->map, "Mosaic map (*.mosaic) to localize against")->check(CLI::ExistingFile);
  command->add_option("--out", args->out, "Report directory")->required();
  command->add_option("--config", args->config, "Localizer configuration (see config/default/localizer.yaml)")
      ->check(CLI::ExistingFile);
  command->add_option("--mode", args->mode,
                      "mosaic (default with --map): localize against the map; "
                      "dead-reckoning: wheel odometry only (the baseline); "
                      "visual-odometry: frame to frame, no map")
      ->check(CLI::IsMember({"mosaic", "dead-reckoning", "visual-odometry"}));
  command->add_option("--required-overlap", args->required_overlap,
                      "Fraction of image overlap the tracker needs (beta of the overlap speed limit)")
      ->check(CLI::Range(0.0, 0.95));
  command->add_option("--start-offset", args->start_offset,
                      "mosaic mode: start this far from the true start, dx_mm,dy_mm,dyaw_deg in the vehicle "
                      "frame (a kidnapped vehicle; relocalization must find it)")
      ->delimiter(',')
      ->expected(3);
  command->add_flag("--relocalize", args->relocalize,
                    "mosaic mode: the start pose is not to be trusted (the vehicle was moved while switched off, "
                    "or the start is a guess): search the map around it and take the one place found, whatever "
                    "the start's uncertainty says");
  command->add_flag("--prefetch", args->prefetch,
                    "mosaic mode: load the map's tiles ahead on threads of their own, as `run` does "
                    "(map.prefetch_horizon_s of the configuration); the estimates do not change");
  return [args, &global] {
    const std::string mode = args->mode.empty() ? (args->map.empty() ? "" : "mosaic") : args->mode;
    if (mode.empty()) {
      core::ThrowInvalidInput("replay: give --map MAP to localize, or --mode dead-reckoning or visual-odometry");
    }
    if (mode == "mosaic" && args->map.empty()) core::ThrowInvalidInput("replay: --mode mosaic needs --map MAP");
    if (mode == "dead-reckoning") {
      RunDeadReckoning(*args, global);
    } else if (mode == "visual-odometry") {
      RunVisualOdometry(*args, global);
    } else {
      RunMosaic(*args, global);
    }
  };
}

}  // namespace mosaicloc::app
