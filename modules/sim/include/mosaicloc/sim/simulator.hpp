#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/sim/encoders.hpp"
#include "mosaicloc/sim/floor.hpp"
#include "mosaicloc/sim/imaging.hpp"
#include "mosaicloc/sim/route.hpp"

namespace mosaicloc::sim {

/// Which floor to drive over.
struct FloorChoice {
  std::string kind = "procedural";  ///< "procedural" or "image"
  std::uint64_t seed = 1;           ///< procedural floor seed, independent of the noise seed
  std::filesystem::path image;      ///< for "image": any image file, tiled over the floor
  /// Texel size, mm. 0 picks the default: 0.125 for procedural, 0.25 for an image.
  double mm_per_texel = 0.0;
  /// The floor a command line names: "procedural", or an image file for kind "image".
  static FloorChoice Named(const std::string& name, FloorChoice base);
  bool Check(std::string* why) const;
};

/// Builds the floor; throws core::Error (invalid input) naming the image file or option.
std::unique_ptr<Floor> MakeFloor(const FloorChoice& choice);

struct SimulatorOptions {
  FloorChoice floor;
  RouteOptions route;
  camera::IdealCameraOptions camera;
  core::Pose2 vehicle_from_camera{200.0, 0.0, 0.0};
  /// The camera's height over the floor as calibrated (`camera` images it at mm_per_px), and
  /// how much higher the real one is: the frames are rendered by a pinhole looking straight
  /// down from camera_height_mm + height_offset_mm, so they show (h + dh) / h times as much
  /// floor per pixel as dataset.yaml says (a vehicle on a higher floor shows less).
  double camera_height_mm = 200.0;
  double height_offset_mm = 0.0;
  ImagingOptions imaging;
  EncoderOptions encoders;
  double frame_rate_hz = 30.0;
  double timestamp_jitter_ms = 0.2;  ///< standard deviation of the capture instants
  double drop_probability = 0.0;     ///< chance that a frame is lost
  std::int64_t frames = 900;         ///< frames to capture, when laps is 0
  int laps = 0;                      ///< complete laps to drive; overrides frames when > 0
  std::uint64_t seed = 1;            ///< noise, path deviation, jitter, drops
  int threads = 2;                   ///< rendering threads; output does not depend on it
  bool Check(std::string* why) const;
};

struct SimulationSummary {
  std::int64_t frames_written = 0;
  std::int64_t frames_dropped = 0;
  std::int64_t encoder_samples = 0;
  double duration_s = 0.0;
  double path_length_m = 0.0;
  double lap_length_m = 0.0;
  double laps_driven = 0.0;
  double max_speed_mps = 0.0;
};

/// Progress in [0, 1]; called from the calling thread.
using ProgressCallback = std::function<void(double fraction)>;

/// Simulates a drive and writes it as a dataset (design.md section 4) to `out`, atomically.
/// Deterministic: the same options give byte-identical files whatever `threads` is.
SimulationSummary Simulate(const SimulatorOptions& options, const std::filesystem::path& out, bool overwrite,
                           const ProgressCallback& progress = {});

}  // namespace mosaicloc::sim
