#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/sim/floor.hpp"
#include "mosaicloc/sim/imaging.hpp"

namespace mosaicloc::sim {

/// A calibration drive over a procedural floor, for `mosaicloc calibrate vehicle`: a straight
/// run, then a turn in place, driven by a vehicle whose true mounting and wheels differ from
/// the nominal values written in the dataset (which is what an integrator knows before
/// calibrating). One encoder sample per frame, at the frame's time. A tricycle drives the
/// straight run with its steered wheel straight ahead, then, standing, turns it across
/// (90 degrees) and pivots about its fixed axle.
struct CalibrationDriveOptions {
  ProceduralFloorOptions floor;
  camera::IdealCameraOptions camera;
  ImagingOptions imaging;
  /// The truth.
  core::Pose2 vehicle_from_camera{212.5, -14.0, 0.035};
  dataset::VehicleInfo vehicle{core::DriveKind::kDifferential, 75.4, 74.7, 507.0, 4096};
  /// What the dataset claims (nominal, before calibration).
  core::Pose2 nominal_vehicle_from_camera{200.0, 0.0, 0.0};
  dataset::VehicleInfo nominal_vehicle{core::DriveKind::kDifferential, 75.0, 75.0, 500.0, 4096};
  double straight_mm = 400.0;
  double step_mm = 10.0;            ///< straight-run advance per frame, at cruising speed
  double turn_rad = 3.14159265358979;
  double turn_step_rad = 0.03;      ///< turn per frame, at cruising speed
  /// Frames over which the straight run and the turn each speed up from rest to cruising
  /// speed and slow down to rest at the end (constant acceleration); 0 = the cruising speed
  /// from the first frame to the last.
  double ramp_frames = 0.0;
  double frame_rate_hz = 30.0;
  std::uint64_t seed = 1;
  bool Check(std::string* why) const;
};

/// The defaults for a vehicle of `kind`: a differential drive's as above, or a tug's tricycle
/// (a 100 mm drive wheel 1.2 m ahead of its axle, a 16-bit absolute steering encoder), whose
/// true wheel radius, wheelbase and steering zero are a little off the nominal ones.
CalibrationDriveOptions CalibrationDriveFor(core::DriveKind kind);

struct CalibrationDriveSummary {
  int frames = 0;
};

/// Writes the drive as a dataset (design.md section 4) with ground truth; the truth of the
/// mounting and wheels also goes into the provenance (keys truth_*). Throws core::Error.
CalibrationDriveSummary WriteCalibrationDrive(const CalibrationDriveOptions& options,
                                              const std::filesystem::path& out, bool overwrite);

}  // namespace mosaicloc::sim
