#include "mosaicloc/sim/calibration_drive.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/dataset/trajectory.hpp"

namespace mosaicloc::sim {
namespace {

// Distances covered after each frame by a vehicle that speeds up from rest to `cruise` per
// frame over `ramp` frames, cruises and slows down to rest the same way, ending at `total`
// (a trapezoidal speed profile; ramp 0 = constant speed from the start).
std::vector<double> Profile(double total, double cruise, double ramp) {
  std::vector<double> at;
  if (ramp <= 0.0) {
    const int n = static_cast<int>(std::lround(total / cruise));
    for (int i = 1; i <= n; ++i) at.push_back(total * i / n);
    return at;
  }
  // Continuous time in frames: ramp up over r, cruise for c, ramp down over r.
  double r = ramp;
  double c = total / cruise - r;
  if (c < 0.0) {  // too short to reach the cruise speed: a triangle
    r = std::sqrt(total / cruise * ramp);
    c = 0.0;
  }
  const double v = total / (r + c);  // the top speed reached
  const double duration = 2.0 * r + c;
  const int n = std::max(1, static_cast<int>(std::ceil(duration)));
  const auto x = [&](double t) {
    if (t < r) return 0.5 * v * t * t / r;
    if (t < r + c) return 0.5 * v * r + v * (t - r);
    const double u = duration - t;
    return total - 0.5 * v * u * u / r;
  };
  for (int i = 1; i <= n; ++i) at.push_back(x(duration * i / n));
  at.back() = total;
  return at;
}

}  // namespace

bool CalibrationDriveOptions::Check(std::string* why) const {
  if (!floor.Check(why) || !camera.Check(why) || !imaging.Check(why)) return false;
  if (!(straight_mm > 0.0 && step_mm > 0.0 && step_mm < straight_mm)) {
    *why = "calibration drive needs 0 < step_mm < straight_mm";
    return false;
  }
  if (!(ramp_frames >= 0.0 && ramp_frames <= 1000.0)) {
    *why = "calibration drive needs 0 <= ramp_frames <= 1000";
    return false;
  }
  if (!(turn_rad > 0.0 && turn_step_rad > 0.0 && turn_step_rad < turn_rad)) {
    *why = "calibration drive needs 0 < turn_step_rad < turn_rad";
    return false;
  }
  if (!(frame_rate_hz > 0.0)) {
    *why = "calibration drive needs a positive frame rate";
    return false;
  }
  if (!vehicle.Check(why) || !nominal_vehicle.Check(why)) return false;
  if (vehicle.kind != nominal_vehicle.kind) {
    *why = "calibration drive: the vehicle and its nominal values must be of one kind";
    return false;
  }
  if (vehicle.kind == core::DriveKind::kMecanum) {
    *why = "calibration drive: none for a mecanum vehicle (the localizer learns its scales from fixes)";
    return false;
  }
  return true;
}

CalibrationDriveOptions CalibrationDriveFor(core::DriveKind kind) {
  CalibrationDriveOptions options;
  if (kind == core::DriveKind::kTricycle) {
    dataset::VehicleInfo nominal;
    nominal.kind = core::DriveKind::kTricycle;
    nominal.drive_wheel_radius_mm = 100.0;
    nominal.wheelbase_mm = 1200.0;
    nominal.ticks_per_revolution = 4096;
    nominal.steering_ticks_per_revolution = 65536;
    nominal.steering_offset_deg = 0.0;
    options.nominal_vehicle = nominal;
    options.vehicle = nominal;
    options.vehicle.drive_wheel_radius_mm = 100.35;
    options.vehicle.wheelbase_mm = 1206.5;
    options.vehicle.steering_offset_deg = 0.42;
    // The steering offset shows only as the heading a straight run gains from it (0.05 degree
    // over a 1.2 m wheelbase: 0.7 mrad per metre), and a pivot cannot tell it from a sideways
    // lever arm: a longer straight run than a differential drive needs.
    options.straight_mm = 1000.0;
  }
  // None is made for a mecanum vehicle: Check() says why.
  if (kind == core::DriveKind::kMecanum) options.vehicle.kind = options.nominal_vehicle.kind = kind;
  return options;
}

CalibrationDriveSummary WriteCalibrationDrive(const CalibrationDriveOptions& options,
                                              const std::filesystem::path& out, bool overwrite) {
  std::string why;
  if (!options.Check(&why)) core::ThrowInvalidInput(why);
  const auto floor = MakeProceduralFloor(options.floor);
  const camera::IdealCamera camera(options.camera);
  const Imager imager(*floor, camera, options.imaging, options.seed);

  dataset::DatasetInfo info;
  info.camera.width_px = options.camera.width_px;
  info.camera.height_px = options.camera.height_px;
  info.camera.mm_per_px = options.camera.mm_per_px;
  info.camera.vehicle_from_camera = options.nominal_vehicle_from_camera;
  info.vehicle = options.nominal_vehicle;
  const bool tricycle = options.vehicle.kind == core::DriveKind::kTricycle;
  info.provenance = {{"generator", tricycle ? "calibration drive: straight run, then a pivot turn about the fixed axle"
                                            : "calibration drive: straight run, then turn in place"},
                     {"floor", floor->Describe()}};
  dataset::RecordVehicleTruth({options.vehicle_from_camera, options.vehicle}, &info);
  dataset::DatasetWriter writer(out, info, overwrite);

  // Wheel angles accumulate exactly; the encoders count whole ticks of the true wheels (a
  // tricycle's steering encoder reads the true angle less its true offset).
  double left_rad = 0.0, right_rad = 0.0, drive_rad = 0.0, steering_rad = 0.0;
  core::Pose2 world_from_vehicle;
  dataset::Trajectory truth;
  const double ticks_per_rad = static_cast<double>(options.vehicle.ticks_per_revolution) / (2.0 * M_PI);
  const std::vector<double> straight_at = Profile(options.straight_mm, options.step_mm, options.ramp_frames);
  const std::vector<double> turn_at = Profile(options.turn_rad, options.turn_step_rad, options.ramp_frames);
  const int straight_frames = static_cast<int>(straight_at.size());
  const int turn_frames = static_cast<int>(turn_at.size());
  // A tricycle stands for one frame between the two while its steered wheel swings across.
  const int swing_frames = tricycle ? 1 : 0;
  const int frames = 1 + straight_frames + swing_frames + turn_frames;
  for (int i = 0; i < frames; ++i) {
    if (i > 0) {
      const bool straight = i <= straight_frames;
      const int turn_index = i - 1 - straight_frames - swing_frames;  // < 0: not turning yet
      const auto step = [](const std::vector<double>& at, int j) { return at[j] - (j > 0 ? at[j - 1] : 0.0); };
      const double forward = straight ? step(straight_at, i - 1) : 0.0;
      const double turn = turn_index >= 0 ? step(turn_at, turn_index) : 0.0;
      if (tricycle) {
        // Straight ahead the drive wheel rolls as far as the axle moves; across, it rolls the
        // wheelbase times the angle turned about the axle.
        steering_rad = straight ? 0.0 : M_PI / 2.0;
        drive_rad += (forward + options.vehicle.wheelbase_mm * turn) / options.vehicle.drive_wheel_radius_mm;
      } else {
        const double half_track = 0.5 * options.vehicle.track_width_mm;
        left_rad += (forward - half_track * turn) / options.vehicle.left_wheel_radius_mm;
        right_rad += (forward + half_track * turn) / options.vehicle.right_wheel_radius_mm;
      }
      world_from_vehicle = world_from_vehicle * core::Pose2(forward, 0.0, turn);
    }
    const core::Timestamp time = core::Timestamp::FromSeconds(1.0 + i / options.frame_rate_hz);
    const core::Pose2 world_from_camera = world_from_vehicle * options.vehicle_from_camera;
    writer.AddFrame(time, imager.Render(world_from_camera, Eigen::Vector2d::Zero(), time.seconds(),
                                        options.seed * 1000003ULL + static_cast<std::uint64_t>(i)));
    dataset::EncoderSample sample;
    sample.time = time;
    if (tricycle) {
      sample.counts.drive_ticks = static_cast<std::int32_t>(std::lround(drive_rad * ticks_per_rad));
      const double read_rad = steering_rad - options.vehicle.steering_offset_deg * M_PI / 180.0;
      sample.counts.steering_ticks = static_cast<std::int32_t>(
          std::lround(read_rad * static_cast<double>(options.vehicle.steering_ticks_per_revolution) / (2.0 * M_PI)));
    } else {
      sample.counts.left_ticks = static_cast<std::int32_t>(std::lround(left_rad * ticks_per_rad));
      sample.counts.right_ticks = static_cast<std::int32_t>(std::lround(right_rad * ticks_per_rad));
    }
    writer.AddEncoderSample(sample);
    truth.push_back({time, world_from_vehicle});
  }
  writer.SetGroundTruth(truth);
  writer.Commit();
  return {frames};
}

}  // namespace mosaicloc::sim
