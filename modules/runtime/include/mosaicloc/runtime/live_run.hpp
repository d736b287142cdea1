#pragma once

#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "mosaicloc/calibration/ground.hpp"
#include "mosaicloc/console/console.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/io/frame_source.hpp"
#include "mosaicloc/io/plc_link.hpp"
#include "mosaicloc/io/v4l2_camera.hpp"
#include "mosaicloc/runtime/settings.hpp"

namespace mosaicloc::sim {
class PlannedDrive;
}  // namespace mosaicloc::sim

namespace mosaicloc::runtime {

/// The live run's settings (config/default/run.yaml gives every key, its unit and default).
struct LiveRunOptions {
  std::filesystem::path map;                 ///< resolved against the config file's folder
  /// Automatic mapping and map updates as the vehicle drives (design.md sections 7d, 7e), on a
  /// thread of their own; the map is opened for writing, and created empty when it does not exist.
  bool mapping = false;
  std::string camera_source = "v4l2";        ///< "v4l2", "dataset" or "simulator"
  dataset::CameraInfo camera;                ///< ideal image geometry and mounting
  dataset::VehicleInfo vehicle;
  io::V4l2Options v4l2;
  std::filesystem::path dataset;             ///< camera_source dataset: the recording to play
  /// When the recording starts playing, seconds since the Unix epoch (wall clock), so a PLC
  /// simulator playing the same recording's encoders can be started in step; 0 = at once.
  double dataset_start_unix_s = 0.0;
  /// camera_source simulator: the simulator configuration (empty: its defaults); played like
  /// a recording, starting at dataset_start_unix_s.
  std::filesystem::path simulator_config;
  /// Ground-plane calibration of a real camera (`mosaicloc calibrate ground`). When given,
  /// the source delivers raw images (a V4L2 camera at the calibration's raw size, or a raw
  /// recording) and every frame is rectified into the ideal image it describes before it
  /// enters the pipeline.
  std::filesystem::path ground;
  std::optional<calibration::GroundCalibration> ground_calibration;

  io::PlcLinkOptions plc;
  /// Poll and output period. Faster than the PLC updates its counters, so a change is seen
  /// soon after it happens; polling, each period is 0.75 to 1.25 times it at random, so the
  /// reads see every phase of the PLC's counter cycle (EncoderStamperOptions::phase_lock).
  double plc_cycle_ms = 5.0;
  double fix_period_ms = 100.0;              ///< periodic fix writes; 0 = only on request
  double heartbeat_timeout_ms = 500.0;       ///< PLC heartbeat frozen this long = stale; 0 = not watched
  /// Age of the counters when read (about half the PLC's own update period), subtracted from
  /// their time stamps.
  double encoder_latency_ms = 0.0;
  /// What is left of the time-stamp error after that, ms (the filter widens its prediction by
  /// speed times this along the heading).
  double encoder_timing_sigma_ms = 3.0;
  /// Counters unchanged this long mean the vehicle stands still: a sample goes to odometry
  /// anyway, so the filter keeps up with the clock.
  double stationary_after_ms = 50.0;
  /// How often the PLC updates the counter registers, ms. Unchanged counters only say the
  /// vehicle stood still until one update period before they were read.
  double counter_period_ms = 10.0;
  /// A PLC that does not answer for up to this long (a timeout and a reconnection) is bridged:
  /// its counters, read again after it, carry the motion over the gap, and frames wait for them
  /// as for late odometry. A longer outage, or a heartbeat gone stale, makes the next reading
  /// only re-seed odometry (a PLC that restarted has its counters back at 0). No PLC restarts
  /// this fast.
  double odometry_bridge_ms = 200.0;
  /// The lock is judged frame by frame: a write whose latest processed frame was captured
  /// longer ago than this reports tracking as degraded (the tracking thread or the camera fell
  /// behind, and the pose written is the encoders' since that frame). Three frames at 30 Hz.
  double lock_age_ms = 100.0;
  /// SCHED_FIFO priority (1-99) of the PLC thread, so that it reads, dates the counters and
  /// writes the fix on time however busy the computer is; 0: normal scheduling. Needs
  /// CAP_SYS_NICE (root, or `setcap cap_sys_nice+ep`); refused, the run says so and goes on.
  int plc_thread_priority = 0;

  core::Pose2 start;                         ///< where the vehicle is when the run starts
  /// The start is not known (start.unknown): the whole map is searched through its place
  /// index until a frame is found (design.md section 7b).
  bool start_unknown = false;
  double start_sigma_mm = 5.0;
  double start_sigma_deg = 1.0;
  /// A frame waits at most this long for the encoder sample that follows it.
  double max_encoder_wait_ms = 100.0;
  /// The integrator's console served while the run lasts (run.yaml console.enabled), or none.
  std::optional<console::ConsoleOptions> console;

  LocalizationSettings localizer;
  /// The ranges of this struct's own fields (each complaint starts with the field's name);
  /// the PLC link, the V4L2 options and the wheels have Check()s of their own.
  bool Check(std::string* why) const;
};


/// The frames a live run localizes, as its configuration chooses them: a V4L2 camera, a
/// recording played in real time or a simulated drive; raw frames made ideal when a ground
/// calibration is given. A recording or a simulated drive brings its own camera and vehicle.
struct LiveSource {
  std::shared_ptr<const sim::PlannedDrive> drive;  ///< the simulated drive, when the simulator is the camera
  std::unique_ptr<io::FrameSource> frames;
  dataset::CameraInfo camera;   ///< the ideal camera the frames come from
  dataset::VehicleInfo vehicle;
  LiveSource();
  LiveSource(LiveSource&&) noexcept;
  ~LiveSource();
};
LiveSource OpenLiveSource(const LiveRunOptions& options);

/// The live system: a camera source, the PLC link and the localizer over the map, on threads
/// of their own (design.md section 1), until the source ends, the duration passes or a stop
/// is asked for. Optionally records what it saw as a dataset, committed on a clean stop only.
class LiveRun {
 public:
  /// The status of the last second, every second (JSON: t_s, lock, fixes_per_s, frames_per_s,
  /// latency_p50_ms, plc, plc_round_trip_ms, plc_errors, requests, answered, x_mm, y_mm, yaw_deg).
  using StatusCallback = std::function<void(const nlohmann::json& status)>;
  /// Polled every 20 ms: a reason to stop (a signal came), or nothing.
  using StopCallback = std::function<std::optional<std::string>()>;

  /// `camera` and `vehicle`: the ideal image and the wheels the frames and counters come from.
  /// `record`: a new dataset directory, or empty. Throws core::Error naming the map, the
  /// device or the link on a bad start.
  LiveRun(const LiveRunOptions& options, std::unique_ptr<io::FrameSource> source, const dataset::CameraInfo& camera,
          const dataset::VehicleInfo& vehicle, const std::filesystem::path& record);
  ~LiveRun();
  LiveRun(const LiveRun&) = delete;
  LiveRun& operator=(const LiveRun&) = delete;

  /// Runs for `duration_s` (0: until the source ends or a stop); the summary (stopped, frames,
  /// fixes, fix_rate, lock_losses, relocalizations, reanchorings, latency and the tracking thread's processing
  /// time per frame (p50, p99), the PLC link's counters, ...). Rethrows
  /// what stopped a thread.
  nlohmann::json Run(double duration_s, const StatusCallback& status = {}, const StopCallback& stop_requested = {});

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mosaicloc::runtime
