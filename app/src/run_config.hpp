#pragma once

#include <filesystem>
#include <optional>
#include <string>

#include <yaml-cpp/yaml.h>

#include "localizer_config.hpp"
#include "mosaicloc/camera/ground.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/io/plc_link.hpp"
#include "mosaicloc/io/v4l2_camera.hpp"

namespace mosaicloc::app {

/// What `mosaicloc run` reads from --config: see config/default/run.yaml for every key,
/// its unit and default.
struct RunConfig {
  std::filesystem::path map;                 ///< resolved against the config file's folder
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
  std::optional<camera::GroundCalibration> ground_calibration;

  io::PlcLinkOptions plc;
  /// Poll and output period. Faster than the PLC updates its counters, so a change is seen
  /// soon after it happens: an encoder sample is stamped at the middle of the poll interval
  /// in which its counters changed.
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

  core::Pose2 start;                         ///< where the vehicle is when the run starts
  double start_sigma_mm = 5.0;
  double start_sigma_deg = 1.0;
  /// A frame waits at most this long for the encoder sample that follows it.
  double max_encoder_wait_ms = 100.0;

  LocalizerConfig localizer;
};

/// Reads a run configuration. Keys left out keep their defaults; every problem (unknown key,
/// wrong type, value out of range, inconsistent register map) is reported at once as a
/// core::Error naming file, line and key.
RunConfig LoadRunConfig(const std::filesystem::path& file);

/// The register map section of a run configuration (also what plc-sim takes).
void ReadRegisterMap(const YAML::Node& node, const std::string& file_name, io::RegisterMap* map);

}  // namespace mosaicloc::app
