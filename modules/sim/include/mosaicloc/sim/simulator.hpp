#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/dataset/camera_truth.hpp"
#include "mosaicloc/sim/encoders.hpp"
#include "mosaicloc/sim/floor.hpp"
#include "mosaicloc/sim/floor_changes.hpp"
#include "mosaicloc/sim/imaging.hpp"
#include "mosaicloc/sim/relief.hpp"
#include "mosaicloc/sim/route.hpp"
#include "mosaicloc/sim/stance.hpp"

namespace mosaicloc::sim {

/// Which floor to drive over.
struct FloorChoice {
  std::string kind = "procedural";  ///< "procedural" or "image"
  std::uint64_t seed = 1;           ///< procedural floor seed, independent of the noise seed
  std::filesystem::path image;      ///< for "image": any image file, laid over the floor
  /// For "image": "repeat" (tiled) or "patches" (a floor that never repeats, cut from the
  /// picture at places drawn from `seed`; ImageFloorOptions::layout), and the patches' spacing.
  std::string image_layout = "repeat";
  double patch_mm = 32.0;
  /// Texel size, mm. 0 picks the default: 0.125 for procedural, 0.25 for an image.
  double mm_per_texel = 0.0;
  /// The floor's shape (FloorShape): the standard deviation of its height over the site, mm
  /// (0: flat), and the shortest wavelength of its waves, m. The same seed gives the same shape.
  double unevenness_mm = 0.0;
  double unevenness_wavelength_m = 2.0;
  /// The floor a command line names: "procedural", or an image file for kind "image".
  static FloorChoice Named(const std::string& name, FloorChoice base);
  bool Check(std::string* why) const;
};

/// Builds the floor; throws core::Error (invalid input) naming the image file or option.
std::unique_ptr<Floor> MakeFloor(const FloorChoice& choice);
/// The relief of `floor` (which must outlive it, built from `choice`), null when its depth is 0;
/// a height image is laid out as the floor's picture is. Throws core::Error naming the height image.
std::unique_ptr<Relief> MakeRelief(const Floor& floor, const FloorChoice& choice, const ReliefOptions& relief);

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
  /// A slow change of the camera's height (load, tyre wear), mm per minute from the start.
  double height_drift_mm_per_min = 0.0;
  /// Radial distortion left after calibration: the k1 of the normalized image radius.
  double residual_k1 = 0.0;
  /// The body's pitch and roll on its wheels; the floor's shape moves it too. When all of
  /// these are zero and the floor is flat, frames are the ideal view from the true height;
  /// otherwise every pixel is a ray of a pinhole at the camera's 3-D pose (CameraPlacement).
  SuspensionOptions suspension;
  /// How the floor has changed since it was mapped (grime, stains, tyre marks along this
  /// drive's lanes, a wet patch, a replaced tile, a lane line); none by default.
  FloorChangeOptions changes;
  /// The floor's relief (joints, grout, pits below the top surface) and the light carried
  /// with the camera; with either, every pixel is a ray followed into the relief and shaded.
  /// None by default.
  ReliefOptions relief;
  LightOptions light;
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

/// The camera of the simulated vehicle on its floor (throws core::Error for bad options).
CameraPlacement MakeCameraPlacement(const SimulatorOptions& options);

/// The frames of a drive as the simulated camera takes them (what Simulate writes), rendered
/// one at a time for a consumer that takes them as they come (the soak: no dataset on disk).
/// Builds the floor (with its changes along `drive`'s lanes), its relief, the camera's
/// placement and the imager once. Render is const and may run on several threads at once.
class FrameRenderer {
 public:
  /// `drive` must outlive the renderer. Throws core::Error (invalid input) for bad options.
  FrameRenderer(const SimulatorOptions& options, const Drive& drive);
  ~FrameRenderer();
  FrameRenderer(const FrameRenderer&) = delete;
  FrameRenderer& operator=(const FrameRenderer&) = delete;

  /// The ideal frame captured `t_s` into the drive (noise seeded by `frame_seed`), and what a
  /// tracker could recover of the view (may be null).
  cv::Mat Render(double t_s, std::uint64_t frame_seed, dataset::CameraTruth* truth = nullptr) const;
  /// The floor as dataset.yaml's provenance names it.
  std::string DescribeFloor() const;
  const CameraPlacement& placement() const { return placement_; }

 private:
  const SimulatorOptions& options_;
  const Drive& drive_;
  std::unique_ptr<Floor> floor_;
  CameraPlacement placement_;
  std::unique_ptr<Relief> relief_;
  Surface surface_;
  bool rays_ = false;
  std::unique_ptr<Imager> imager_;
};

/// Seeds for frame k of a drive seeded `seed` (SplitMix64), as Simulate draws them.
std::uint64_t FrameSeed(std::uint64_t seed, std::uint64_t k);

/// A drive as Simulate makes it, before anything is written: the route driven, the capture
/// instants (jitter and drops drawn), what the dataset's header says, and the frames and
/// encoder samples on demand. Simulate writes it; a live source plays it as it goes (each frame
/// rendered when it is due, each encoder sample computed when it is), so that a drive of hours
/// needs no recording on disk and both sides of a live run, given the same options, play the
/// same drive. Memory: the drive's path (every 5 mm) and one time per frame.
class PlannedDrive {
 public:
  /// Throws core::Error (invalid input) for bad options, or when every frame was dropped.
  explicit PlannedDrive(const SimulatorOptions& options);
  ~PlannedDrive();
  PlannedDrive(const PlannedDrive&) = delete;
  PlannedDrive& operator=(const PlannedDrive&) = delete;

  const SimulatorOptions& options() const { return options_; }
  const Drive& drive() const { return drive_; }
  /// dataset.yaml's header: the camera, the vehicle as calibrated, the provenance.
  const dataset::DatasetInfo& info() const { return info_; }
  /// The frames' capture instants, s from the drive's start (the dropped ones left out).
  const std::vector<double>& capture_s() const { return capture_s_; }
  std::int64_t frames_dropped() const { return frames_dropped_; }
  /// Frame k of capture_s(), rendered (thread-safe), and what a tracker could recover of it.
  cv::Mat RenderFrame(std::size_t k, dataset::CameraTruth* truth = nullptr) const;
  /// The vehicle's true pose t_s into the drive.
  core::Pose2 TruthAt(double t_s) const;

  /// The encoder samples, from the start to just past the last frame, in order (the encoder
  /// model carries slip and backlash from one sample to the next). Each stream starts again
  /// from the first sample.
  class EncoderStream {
   public:
    explicit EncoderStream(const PlannedDrive& plan);
    /// The next sample, or nothing after the last.
    std::optional<dataset::EncoderSample> Next();

   private:
    const PlannedDrive& plan_;
    EncoderModel model_;
    std::int64_t next_ = 0;
  };
  EncoderStream Encoders() const { return EncoderStream(*this); }

 private:
  SimulatorOptions options_;
  int laps_ = 1;
  Drive drive_;
  std::unique_ptr<FrameRenderer> renderer_;
  std::vector<double> capture_s_;
  std::int64_t frames_dropped_ = 0;
  dataset::DatasetInfo info_;
};

/// Progress in [0, 1]; called from the calling thread.
using ProgressCallback = std::function<void(double fraction)>;

/// Simulates a drive and writes it as a dataset (design.md section 4) to `out`, atomically.
/// Deterministic: the same options give byte-identical files whatever `threads` is.
SimulationSummary Simulate(const SimulatorOptions& options, const std::filesystem::path& out, bool overwrite,
                           const ProgressCallback& progress = {});

}  // namespace mosaicloc::sim
