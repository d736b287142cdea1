#include <algorithm>
#include <chrono>
#include <cstdio>
#include <vector>

#include "commands.hpp"
#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/file.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/dataset/evaluation.hpp"
#include "mosaicloc/estimation/odometry.hpp"
#include "progress.hpp"
#include "report.hpp"

namespace mosaicloc::app {
namespace {

struct ReplayArgs {
  std::filesystem::path dataset;
  std::filesystem::path out;
  std::string mode = "dead-reckoning";
  double required_overlap = 0.5;
};

// Dead reckoning: integrate the wheel encoders from the starting pose, and report the pose
// at every frame's time. This is the baseline the mosaic fix removes the drift from.
void RunDeadReckoning(const ReplayArgs& args, const GlobalOptions& global) {
  const dataset::DatasetReader reader(args.dataset);
  const dataset::DatasetInfo& info = reader.info();
  std::optional<dataset::Trajectory> groundtruth;
  if (reader.HasGroundTruth()) groundtruth = reader.GroundTruth();

  estimation::DiffDriveOptions odometry_options;
  odometry_options.left_wheel_radius_mm = info.vehicle.left_wheel_radius_mm;
  odometry_options.right_wheel_radius_mm = info.vehicle.right_wheel_radius_mm;
  odometry_options.track_width_mm = info.vehicle.track_width_mm;
  odometry_options.ticks_per_revolution = info.vehicle.ticks_per_revolution;
  // The start is known (as a localizer would be told at installation): the first ground
  // truth pose, or the origin.
  const core::Pose2 start = groundtruth ? groundtruth->front().world_from_vehicle : core::Pose2::Identity();
  estimation::DiffDriveOdometry odometry(odometry_options, start);

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

  ProgressBar progress("replay", global.quiet);
  dataset::Trajectory estimate;
  std::vector<double> latency_ms;
  std::int64_t frames = 0;
  const auto started = std::chrono::steady_clock::now();
  auto stream = reader.Frames();
  while (true) {
    const auto frame_start = std::chrono::steady_clock::now();
    const auto frame = stream.Next(/*decode=*/false);
    if (!frame) break;
    ++frames;
    const auto pose = dataset::PoseAt(integrated, frame->time, std::chrono::milliseconds(100));
    if (pose) estimate.push_back({frame->time, *pose});
    latency_ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - frame_start).count());
    if (frames % 64 == 0 && groundtruth) {
      progress.Update(std::clamp((frame->time - groundtruth->front().time).count() /
                                     static_cast<double>((groundtruth->back().time - groundtruth->front().time).count() + 1),
                                 0.0, 1.0));
    }
  }
  const double elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  progress.Finish();
  if (estimate.empty()) core::ThrowInvalidInput(args.dataset.string() + ": no frame falls within the encoder samples");

  dataset::Metrics metrics;
  metrics.frames = frames;
  metrics.fixes = 0;  // dead reckoning makes no visual fix
  metrics.fix_rate = 0.0;
  metrics.processing_fps = elapsed_s > 0.0 ? static_cast<double>(frames) / elapsed_s : 0.0;
  std::sort(latency_ms.begin(), latency_ms.end());  // not empty: estimate has a frame
  metrics.latency_p50_ms = dataset::Percentile(latency_ms, 50.0);
  metrics.latency_p99_ms = dataset::Percentile(latency_ms, 99.0);
  // Overlap speed limit (founding paper, section 2.2): V < (footprint along travel / T) (1 - beta).
  const camera::IdealCamera camera(
      camera::IdealCameraOptions{info.camera.width_px, info.camera.height_px, info.camera.mm_per_px});
  if (estimate.size() > 1) {
    const double period_s = core::ToSeconds(estimate.back().time - estimate.front().time) /
                            static_cast<double>(estimate.size() - 1);
    const double along_mm = camera.FootprintLengthAlong(-info.camera.vehicle_from_camera.yaw_rad());
    metrics.overlap_speed_limit_mps = along_mm * 1e-3 / period_s * (1.0 - args.required_overlap);
  }

  std::error_code ec;
  std::filesystem::create_directories(args.out, ec);
  core::WriteFileAtomically(args.out / "fixes.csv", "#timestamp_ns,x_mm,y_mm,yaw_rad,status,quality\n");
  const dataset::Metrics written = WriteReport(args.out, estimate, groundtruth, metrics,
                                               "dead reckoning: " + args.dataset.filename().string());
  if (rejected > 0) core::Log().warn("{} encoder samples rejected", rejected);
  PrintMetrics(args.out, written, global.json);
}

}  // namespace

Action AddReplayCommand(CLI::App& app, const GlobalOptions& global) {
  auto args = std::make_shared<ReplayArgs>();
  CLI::App* command = app.add_subcommand("replay", "Localize a recorded or simulated dataset and write a report");
  command->add_option("--dataset", args->dataset, "Dataset directory")->required();
  command->add_option("--out", args->out, "Report directory")->required();
  command->add_option("--mode", args->mode, "dead-reckoning: wheel odometry only (the baseline)")
      ->check(CLI::IsMember({"dead-reckoning"}));
  command->add_option("--required-overlap", args->required_overlap,
                      "Fraction of image overlap the tracker needs (beta of the overlap speed limit)")
      ->check(CLI::Range(0.0, 0.95));
  return [args, &global] { RunDeadReckoning(*args, global); };
}

}  // namespace mosaicloc::app
