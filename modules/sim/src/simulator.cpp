#include "mosaicloc/sim/simulator.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>
#include <vector>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/worker_pool.hpp"
#include "mosaicloc/dataset/dataset.hpp"

namespace mosaicloc::sim {
namespace {

// SplitMix64: independent, reproducible seeds per frame from one seed.
std::uint64_t Mix(std::uint64_t seed, std::uint64_t index) {
  std::uint64_t z = seed + 0x9e3779b97f4a7c15ULL * (index + 1);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

std::string Number(double value) {
  std::ostringstream out;
  out.precision(10);
  out << value;
  return out.str();
}

// The vehicle's (longitudinal, lateral) acceleration at t, m/s^2, from the drive's speed and
// turn rate over 10 ms either side.
Eigen::Vector2d Acceleration(const Drive& drive, double t) {
  constexpr double kH = 0.01;
  const VehicleState before = drive.At(t - kH);
  const VehicleState now = drive.At(t);
  const VehicleState after = drive.At(t + kH);
  const double longitudinal = (after.forward_speed_mps - before.forward_speed_mps) / (2 * kH);
  const double turn_rate = core::YawDifference(after.world_from_vehicle, before.world_from_vehicle) / (2 * kH);
  return {longitudinal, now.forward_speed_mps * turn_rate};
}

// The lanes' wheel paths (where tyre marks build up): the route's centre line, one lap,
// offset by half the marks' track width (the vehicle's true one unless given) to either side.
std::vector<std::vector<Eigen::Vector2d>> WheelPaths(const Drive& drive, const SimulatorOptions& options) {
  const double half_track =
      options.changes.tyre_track_width_mm > 0.0
          ? 0.5 * options.changes.tyre_track_width_mm
          : 0.5 * options.encoders.nominal.track_width_mm * (1.0 + options.encoders.track_width_error);
  std::vector<std::vector<Eigen::Vector2d>> paths(2);
  constexpr double kStepM = 0.02;
  for (double s = 0.0; s <= drive.lap_length_m() + 0.5 * kStepM; s += kStepM) {
    const core::Pose2 centre = drive.CentreLineAt(std::min(s, drive.lap_length_m()));
    paths[0].push_back(centre * Eigen::Vector2d(0.0, half_track));
    paths[1].push_back(centre * Eigen::Vector2d(0.0, -half_track));
  }
  return paths;
}

/// An image floor of `image` laid out as `choice` says (mm_per_texel 0: the default).
ImageFloorOptions ImageLayout(const FloorChoice& choice, const std::filesystem::path& image, double mm_per_texel) {
  ImageFloorOptions options;
  options.image = image;
  if (mm_per_texel > 0.0) options.mm_per_texel = mm_per_texel;
  options.layout = choice.image_layout;
  options.patch_mm = choice.patch_mm;
  options.seed = choice.seed;
  return options;
}

}  // namespace

FloorChoice FloorChoice::Named(const std::string& name, FloorChoice base) {
  base.kind = name == "procedural" ? "procedural" : "image";
  base.image = name == "procedural" ? std::filesystem::path() : std::filesystem::path(name);
  return base;
}

bool FloorChoice::Check(std::string* why) const {
  if (kind != "procedural" && kind != "image") {
    *why = "kind must be procedural or image, got '" + kind + "'";
    return false;
  }
  if (kind == "image" && image.empty()) {
    *why = "image must name an image file when kind is image";
    return false;
  }
  if (image_layout != "repeat" && image_layout != "patches") {
    *why = "image_layout must be repeat or patches, got '" + image_layout + "'";
    return false;
  }
  if (!(patch_mm >= 1.0 && patch_mm <= 10000.0)) {
    *why = "patch_mm must be in [1, 10000]";
    return false;
  }
  if (!(mm_per_texel >= 0.0 && mm_per_texel <= 100.0)) {
    *why = "mm_per_texel must be in [0, 100] (0: the floor's default)";
    return false;
  }
  if (!(unevenness_mm >= 0.0 && unevenness_mm <= 50.0)) {
    *why = "unevenness_mm must be in [0, 50]";
    return false;
  }
  if (!(unevenness_wavelength_m >= 0.2 && unevenness_wavelength_m <= 100.0)) {
    *why = "unevenness_wavelength_m must be in [0.2, 100]";
    return false;
  }
  return true;
}

std::unique_ptr<Floor> MakeFloor(const FloorChoice& choice) {
  std::string why;
  if (!choice.Check(&why)) core::ThrowInvalidInput("floor: " + why);
  if (choice.kind == "procedural") {
    ProceduralFloorOptions options;
    options.seed = choice.seed;
    if (choice.mm_per_texel > 0.0) options.mm_per_texel = choice.mm_per_texel;
    return MakeProceduralFloor(options);
  }
  if (choice.kind == "image") {
    return MakeImageFloor(ImageLayout(choice, choice.image, choice.mm_per_texel));
  }
  core::ThrowInvalidInput("floor: kind '" + choice.kind + "'");  // Check() refused it above
}

std::unique_ptr<Relief> MakeRelief(const Floor& floor, const FloorChoice& choice, const ReliefOptions& relief) {
  std::string why;
  if (!relief.Check(&why)) core::ThrowInvalidInput("relief: " + why);
  if (!relief.any()) return nullptr;
  if (relief.source == "albedo") return std::make_unique<Relief>(floor, relief);
  // The height image lies on the floor's texel grid, cut as the floor's picture is.
  return std::make_unique<Relief>(MakeImageFloor(ImageLayout(choice, relief.height_image, floor.mm_per_texel())), relief);
}

bool SimulatorOptions::Check(std::string* why) const {
  if (!(frame_rate_hz > 0.0 && frame_rate_hz <= 10000.0)) {
    *why = "frame_rate_hz must be in (0, 10000]";
    return false;
  }
  if (!(timestamp_jitter_ms >= 0.0 && timestamp_jitter_ms < 250.0 / frame_rate_hz)) {
    *why = "timestamp_jitter_ms must be >= 0 and under a quarter of the frame period";
    return false;
  }
  if (!(drop_probability >= 0.0 && drop_probability < 1.0)) {
    *why = "drop_probability must be in [0, 1)";
    return false;
  }
  if (laps < 0 || (laps == 0 && frames < 1)) {
    *why = "give frames >= 1 or laps >= 1";
    return false;
  }
  if (frames > 100'000'000 || laps > 100'000) {
    *why = "frames must be at most 1e8 and laps at most 1e5";
    return false;
  }
  if (!(camera_height_mm >= 10.0 && camera_height_mm <= 5000.0)) {
    *why = "camera_height_mm must be in [10, 5000]";
    return false;
  }
  if (!(std::abs(height_offset_mm) <= 0.2 * camera_height_mm)) {
    *why = "height_offset_mm must be within 20 % of camera_height_mm";
    return false;
  }
  if (!(std::abs(height_drift_mm_per_min) <= 10.0)) {
    *why = "height_drift_mm_per_min must be within [-10, 10]";
    return false;
  }
  if (!(std::abs(residual_k1) <= 0.1)) {
    *why = "residual_k1 must be within [-0.1, 0.1]";
    return false;
  }
  if (threads < 1 || threads > 64) {
    *why = "threads must be in [1, 64]";
    return false;
  }
  // The parts last, so that a complaint about a field of this struct is not hidden by one of theirs.
  if (!floor.Check(why)) {
    *why = "floor." + *why;
    return false;
  }
  if (!suspension.Check(why)) {
    *why = "suspension." + *why;
    return false;
  }
  if (!changes.Check(why)) {
    *why = "changes." + *why;
    return false;
  }
  if (!relief.Check(why)) {
    *why = "relief." + *why;
    return false;
  }
  if (!light.Check(why)) {
    *why = "light." + *why;
    return false;
  }
  if (light.any() && !(camera_height_mm + light.height_over_lens_mm > 1.0)) {
    *why = "light.height_over_lens_mm puts the ring light below the floor";
    return false;
  }
  if (!(route.Check(why) && camera.Check(why) && imaging.Check(why) && encoders.Check(why))) return false;
  if (encoders.nominal.kind == core::DriveKind::kTricycle && !(route.curvature_transition_m > 0.0)) {
    *why = "route.curvature_transition_m must be > 0 for a tricycle (its steered wheel cannot swing into a bend at once; "
           "0.5 m is a typical guide path's)";
    return false;
  }
  if (encoders.nominal.kind != core::DriveKind::kMecanum && route.crab_amplitude_deg > 0.0) {
    *why = std::string("route.crab_amplitude_deg must be 0 for a ") + core::ToString(encoders.nominal.kind) +
           " (only a mecanum vehicle moves sideways)";
    return false;
  }
  return true;
}

CameraPlacement MakeCameraPlacement(const SimulatorOptions& options) {
  CameraPlacementOptions placement;
  placement.calibrated_height_mm = options.camera_height_mm;
  placement.height_offset_mm = options.height_offset_mm;
  placement.height_drift_mm_per_min = options.height_drift_mm_per_min;
  placement.residual_k1 = options.residual_k1;
  placement.vehicle_from_camera = options.vehicle_from_camera;
  placement.track_width_mm = options.encoders.nominal.track_width_mm * (1.0 + options.encoders.track_width_error);
  placement.suspension = options.suspension;
  placement.unevenness_mm = options.floor.unevenness_mm;
  placement.unevenness_wavelength_m = options.floor.unevenness_wavelength_m;
  placement.floor_seed = options.floor.seed;
  const camera::IdealCamera camera(options.camera);
  return CameraPlacement(placement, camera.mm_per_px(), camera.cx(), camera.cy());
}

FrameRenderer::FrameRenderer(const SimulatorOptions& options, const Drive& drive)
    : options_(options), drive_(drive), placement_(MakeCameraPlacement(options)) {
  floor_ = MakeFloor(options.floor);
  // The relief is the floor's own, not its changes' (grime lies on the tops and in the joints).
  const Floor* base = floor_.get();  // kept alive by `floor_`, which may wrap it
  relief_ = MakeRelief(*base, options.floor, options.relief);
  if (options.changes.any()) floor_ = ChangedFloor(std::move(floor_), options.changes, WheelPaths(drive, options));
  surface_ = Surface{relief_.get(), options.light, options.camera_height_mm};
  // The frames as the camera really sees them: straight down from its true height, or
  // through the rays of its 3-D pose (into the relief, under the camera's light).
  rays_ = !placement_.straight_down() || surface_.any();
  const camera::IdealCamera camera(options.camera);
  const camera::IdealCamera seen =
      rays_ ? camera : camera.Scaled((options.camera_height_mm + options.height_offset_mm) / options.camera_height_mm);
  imager_ = std::make_unique<Imager>(*floor_, seen, options.imaging, options.seed, surface_);
}

FrameRenderer::~FrameRenderer() = default;

std::string FrameRenderer::DescribeFloor() const { return floor_->Describe(); }

cv::Mat FrameRenderer::Render(double t, std::uint64_t frame_seed, dataset::CameraTruth* truth) const {
  const core::Pose2 world_from_vehicle = drive_.At(t).world_from_vehicle;
  const core::Pose2 world_from_camera = world_from_vehicle * options_.vehicle_from_camera;
  constexpr double kHalfStepS = 5e-4;
  const core::Pose2 before = drive_.At(t - kHalfStepS).world_from_vehicle * options_.vehicle_from_camera;
  const core::Pose2 after = drive_.At(t + kHalfStepS).world_from_vehicle * options_.vehicle_from_camera;
  const Eigen::Vector2d velocity_camera =
      world_from_camera.Rotation().transpose() * (after.translation_mm() - before.translation_mm()) / (2 * kHalfStepS);
  const CameraView view = placement_.At(world_from_vehicle, Acceleration(drive_, t), t);
  if (truth != nullptr) *truth = placement_.Truth(view, world_from_vehicle);
  const auto to_floor = [&](const Eigen::Vector2d& pixel) { return placement_.PixelToWorld(view, pixel); };
  if (surface_.any()) {
    SurfaceView surface_view{view.lens_mm, view.world_from_camera, {}};
    if (!placement_.floor().flat()) {
      surface_view.floor_height_mm = [&](const Eigen::Vector2d& xy) { return placement_.floor().HeightMm(xy); };
    }
    return imager_->Render(to_floor, surface_view, velocity_camera, t, frame_seed);
  }
  if (rays_) return imager_->Render(to_floor, velocity_camera, t, frame_seed);
  return imager_->Render(world_from_camera, velocity_camera, t, frame_seed);
}

std::uint64_t FrameSeed(std::uint64_t seed, std::uint64_t k) { return Mix(seed, k + 1); }

namespace {

// The frames Simulate captures: as many as the laps take, or options.frames.
int LapsOf(const SimulatorOptions& options) {
  std::string why;
  if (!options.Check(&why)) core::ThrowInvalidInput("simulate: " + why);
  return options.laps > 0 ? options.laps
                          : Drive::LapsForFrames(options.route, options.frames, options.frame_rate_hz);
}

}  // namespace

PlannedDrive::PlannedDrive(const SimulatorOptions& options)
    : options_(options), laps_(LapsOf(options)), drive_(options_.route, laps_, options_.seed) {
  renderer_ = std::make_unique<FrameRenderer>(options_, drive_);
  const CameraPlacement& placement = renderer_->placement();
  const double period_s = 1.0 / options_.frame_rate_hz;
  const std::int64_t frames = options_.laps > 0
                                  ? static_cast<std::int64_t>(std::floor(drive_.duration_s() / period_s)) + 1
                                  : options_.frames;

  // Capture instants (with jitter) and which frames are lost, drawn up front so they do
  // not depend on rendering order.
  std::mt19937_64 rng(Mix(options_.seed, 0xf4a3e5ULL));
  std::normal_distribution<double> jitter(0.0, options_.timestamp_jitter_ms * 1e-3);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  capture_s_.reserve(static_cast<std::size_t>(frames));
  for (std::int64_t k = 0; k < frames; ++k) {
    const double j = std::clamp(jitter(rng), -0.25 * period_s, 0.25 * period_s);
    const bool dropped = unit(rng) < options_.drop_probability;
    if (dropped) {
      ++frames_dropped_;
      continue;
    }
    capture_s_.push_back(std::max(0.0, static_cast<double>(k) * period_s + j));
  }
  if (capture_s_.empty()) core::ThrowInvalidInput("simulate: every frame was dropped; lower drop_probability");

  dataset::DatasetInfo& info = info_;
  info.camera.width_px = options_.camera.width_px;
  info.camera.height_px = options_.camera.height_px;
  info.camera.mm_per_px = options_.camera.mm_per_px;
  info.camera.vehicle_from_camera = options_.vehicle_from_camera;
  info.vehicle = options_.encoders.nominal;
  auto& p = info.provenance;
  p["source"] = "mosaicloc simulate";
  p["floor"] = renderer_->DescribeFloor();
  p["route"] = options_.route.name;
  p["laps"] = std::to_string(laps_);
  p["speed_mps"] = Number(options_.route.speed_mps);
  p["seed"] = std::to_string(options_.seed);
  p["frame_rate_hz"] = Number(options_.frame_rate_hz);
  p["exposure_us"] = Number(options_.imaging.exposure_us);
  p["noise_std_dn"] = Number(options_.imaging.noise_std_dn);
  p["lateral_deviation_mm"] = Number(options_.route.lateral_deviation_mm);
  p["encoder_rate_hz"] = Number(options_.encoders.rate_hz);
  const EncoderOptions& e = options_.encoders;
  if (e.nominal.kind == core::DriveKind::kTricycle) {
    p["true_drive_wheel_radius_mm"] = Number(e.nominal.drive_wheel_radius_mm * (1.0 + e.drive_radius_error));
    p["true_wheelbase_mm"] = Number(e.nominal.wheelbase_mm * (1.0 + e.wheelbase_error));
    p["true_steering_offset_deg"] = Number(e.nominal.steering_offset_deg + e.steering_offset_error_deg);
    p["steering_backlash_deg"] = Number(e.steering_backlash_deg);
  } else if (e.nominal.kind == core::DriveKind::kMecanum) {
    p["true_mecanum_wheel_radius_mm"] = Number(e.nominal.mecanum_wheel_radius_mm * (1.0 + e.mecanum_radius_error));
    p["true_track_width_mm"] = Number(e.nominal.track_width_mm * (1.0 + e.track_width_error));
    p["true_wheelbase_mm"] = Number(e.nominal.wheelbase_mm * (1.0 + e.wheelbase_error));
    p["lateral_slip"] = Number(e.lateral_slip);
    p["crab_amplitude_deg"] = Number(options_.route.crab_amplitude_deg);
    p["crab_wavelength_m"] = Number(options_.route.crab_wavelength_m);
  } else {
    p["true_left_wheel_radius_mm"] = Number(e.nominal.left_wheel_radius_mm * (1.0 + e.left_radius_error));
    p["true_right_wheel_radius_mm"] = Number(e.nominal.right_wheel_radius_mm * (1.0 + e.right_radius_error));
    p["true_track_width_mm"] = Number(e.nominal.track_width_mm * (1.0 + e.track_width_error));
  }
  p["wheel_slip_std"] = Number(options_.encoders.slip_std);
  p["camera_height_mm"] = Number(options_.camera_height_mm);
  p["height_offset_mm"] = Number(options_.height_offset_mm);
  if (!placement.straight_down()) {
    p["height_drift_mm_per_min"] = Number(options_.height_drift_mm_per_min);
    p["residual_k1"] = Number(options_.residual_k1);
    p["unevenness_mm"] = Number(options_.floor.unevenness_mm);
    p["unevenness_wavelength_m"] = Number(options_.floor.unevenness_wavelength_m);
    p["pitch_deg_per_mps2"] = Number(options_.suspension.pitch_deg_per_mps2);
    p["roll_deg_per_mps2"] = Number(options_.suspension.roll_deg_per_mps2);
    p["pivot_height_mm"] = Number(options_.suspension.pivot_height_mm);
    p["caster_x_mm"] = Number(options_.suspension.caster_x_mm);
  }
  if (options_.relief.any()) {
    p["relief_depth_mm"] = Number(options_.relief.depth_mm);
    p["relief_source"] = options_.relief.source == "image" ? options_.relief.height_image.string() : "albedo";
    p["relief_low_fraction"] = Number(options_.relief.low_fraction);
    p["relief_slope_fraction"] = Number(options_.relief.slope_fraction);
    p["relief_smoothing_mm"] = Number(options_.relief.smoothing_mm);
  }
  if (options_.light.any()) {
    p["light_sources"] = std::to_string(options_.light.sources);
    p["light_ring_radius_mm"] = Number(options_.light.ring_radius_mm);
    p["light_height_over_lens_mm"] = Number(options_.light.height_over_lens_mm);
    p["light_ambient"] = Number(options_.light.ambient);
    p["light_ring_gain"] = Number(options_.light.ring_gain);
  }
}

PlannedDrive::~PlannedDrive() = default;

cv::Mat PlannedDrive::RenderFrame(std::size_t k, dataset::CameraTruth* truth) const {
  return renderer_->Render(capture_s_.at(k), FrameSeed(options_.seed, k), truth);
}

core::Pose2 PlannedDrive::TruthAt(double t_s) const { return drive_.At(t_s).world_from_vehicle; }

PlannedDrive::EncoderStream::EncoderStream(const PlannedDrive& plan)
    : plan_(plan), model_(plan.options_.encoders, plan.options_.seed) {}

std::optional<dataset::EncoderSample> PlannedDrive::EncoderStream::Next() {
  // Samples from the start to just past the last frame.
  const double end_s = plan_.capture_s_.back() + 1.0 / plan_.options_.frame_rate_hz;
  const double t = static_cast<double>(next_) / plan_.options_.encoders.rate_hz;
  if (t > end_s) return std::nullopt;
  ++next_;
  return model_.Step(core::Timestamp::FromSeconds(t), plan_.drive_.At(t).world_from_vehicle,
                     plan_.drive_.At(t + kSteeringInstantS).world_from_vehicle);
}

SimulationSummary Simulate(const SimulatorOptions& options, const std::filesystem::path& out, bool overwrite,
                           const ProgressCallback& progress) {
  const PlannedDrive plan(options);
  const Drive& drive = plan.drive();
  const std::vector<double>& capture_s = plan.capture_s();
  SimulationSummary summary;
  summary.frames_dropped = plan.frames_dropped();

  dataset::DatasetWriter writer(out, plan.info(), overwrite);
  PlannedDrive::EncoderStream encoders = plan.Encoders();
  while (const std::optional<dataset::EncoderSample> sample = encoders.Next()) {
    writer.AddEncoderSample(*sample);
    ++summary.encoder_samples;
  }

  // Frames, rendered in parallel batches and written in order.
  dataset::Trajectory groundtruth;
  groundtruth.reserve(capture_s.size());
  std::string camera_csv = dataset::CameraTruthHeader();
  const std::size_t batch = 8 * static_cast<std::size_t>(options.threads);
  std::vector<std::vector<unsigned char>> encoded(batch);
  std::vector<dataset::CameraTruth> camera_truth(batch);
  core::WorkerPool workers(options.threads);
  for (std::size_t first = 0; first < capture_s.size(); first += batch) {
    const std::size_t count = std::min(batch, capture_s.size() - first);
    workers.Run(count, [&](std::size_t i) {
      encoded[i] = dataset::DatasetWriter::EncodeFrame(plan.RenderFrame(first + i, &camera_truth[i]));
    });
    for (std::size_t i = 0; i < count; ++i) {
      const auto time = core::Timestamp::FromSeconds(capture_s[first + i]);
      writer.AddEncodedFrame(time, encoded[i]);
      groundtruth.push_back({time, plan.TruthAt(capture_s[first + i])});
      camera_csv += dataset::CameraTruthRow(time, camera_truth[i]);
    }
    if (progress) progress(static_cast<double>(first + count) / static_cast<double>(capture_s.size()));
  }
  writer.SetGroundTruth(groundtruth);
  writer.AddFile(dataset::kCameraTruthFile, camera_csv);
  writer.Commit();

  summary.frames_written = static_cast<std::int64_t>(capture_s.size());
  summary.duration_s = capture_s.back();
  summary.path_length_m = drive.At(capture_s.back()).path_distance_m;
  summary.lap_length_m = drive.lap_length_m();
  summary.laps_driven = summary.path_length_m / drive.lap_length_m();
  summary.max_speed_mps = drive.max_speed_mps();
  return summary;
}

}  // namespace mosaicloc::sim
