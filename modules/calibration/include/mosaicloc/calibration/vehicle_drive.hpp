#pragma once

#include <array>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include "mosaicloc/calibration/vehicle_calibration.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/core/wheel_geometry.hpp"

namespace mosaicloc::calibration {

/// How a calibration drive's frames are registered into DriveSteps.
struct VehicleDriveOptions {
  /// Each frame is registered to the one before it (the chain that predicts the others) and
  /// to up to `baselines` earlier frames it still overlaps, evenly spread: the longer the
  /// baseline, the smaller a registration error is against the motion.
  int baselines = 12;
  /// Earlier frames overlapping the current one by less than this share are dropped.
  double min_overlap = 0.2;
  /// The prior of a consecutive registration around the last registered motion (the drive
  /// is smooth) or, after a failure, the nominal odometry.
  double prior_sigma_mm = 3.0;
  double prior_sigma_rad = 0.01;
  bool Check(std::string* why) const;
};

/// The six calibrated values in the order of VehicleCalibrationResult::sigma: x_mm, y_mm,
/// yaw_rad of vehicle_from_camera, then left radius, right radius, track width (mm) of a
/// differential drive, or drive wheel radius, wheelbase (mm) and steering offset (rad) of a
/// tricycle.
using VehicleParameters = std::array<double, 6>;

/// How a kind's six values are shown: a label for a table, the key of the calibration file
/// and of `calibrate vehicle --json` (the yaw and the steering offset in degrees), and the
/// factor from the value to the unit shown.
struct VehicleParameterNames {
  std::array<const char*, 6> labels;
  std::array<const char*, 6> keys;
  std::array<double, 6> shown_per_value;
};
const VehicleParameterNames& ParameterNamesOf(core::DriveKind kind);

struct VehicleDriveResult {
  core::DriveKind kind = core::DriveKind::kDifferential;
  VehicleCalibrationResult calibration;
  int frames = 0;                ///< frames of the drive
  int steps = 0;                 ///< registered pairs, all baselines
  int consecutive_steps = 0;     ///< registered pairs of consecutive frames
  int not_registered = 0;        ///< consecutive pairs that failed to register
  VehicleParameters value{};  ///< the calibrated values, from `calibration`
  VehicleParameters sigma{};  ///< their one-sigma uncertainties
  /// The truth a simulated drive records in its provenance, when it does.
  std::optional<VehicleParameters> truth;
};

/// The six values of a mounting and wheel geometry, in VehicleParameters' order.
VehicleParameters ToVehicleParameters(const core::Pose2& vehicle_from_camera, const core::WheelGeometry& wheels);

/// Calibrates the camera's place on the vehicle and the wheel geometry from a recorded
/// calibration drive (ideal images and encoders: a straight run, then a turn in place; a
/// tricycle's with its steered wheel across, pivoting about the fixed axle).
/// The lens's vignetting is estimated from the drive and divided out; each frame is
/// registered to the one before and to earlier overlapping frames with the tracker's matcher
/// set for accuracy (the whole frame in templates, a wider low-pass), and CalibrateVehicle
/// fits the result from the dataset's nominal values. Throws core::Error (invalid input)
/// naming the dataset when the drive has no encoders or the fit fails. `progress` (may be
/// empty) is called with the fraction of frames done.
VehicleDriveResult CalibrateVehicleFromDrive(const std::filesystem::path& dataset, const VehicleDriveOptions& options,
                                             const std::function<void(double)>& progress = {});

/// A vehicle calibration file (`mosaicloc calibrate vehicle --out`, design.md section 4).
struct VehicleCalibrationFile {
  core::Pose2 vehicle_from_camera;
  core::WheelGeometry wheels;  ///< its kind and the kind's three values (no encoder counts per turn)
  VehicleParameters sigma{};   ///< one-sigma uncertainties, as the result's
};

/// Writes the file atomically; `comment` goes at its top.
void WriteVehicleCalibration(const std::filesystem::path& file, const VehicleCalibrationFile& calibration,
                             const std::string& comment);
/// Writes what a calibration drive of `dataset` found, with a comment saying where it came
/// from and where its values go.
void WriteVehicleCalibration(const std::filesystem::path& file, const VehicleDriveResult& drive,
                             const std::filesystem::path& dataset);
/// Reads and checks it; throws core::Error naming the file, line and key on bad input.
VehicleCalibrationFile ReadVehicleCalibration(const std::filesystem::path& file);

}  // namespace mosaicloc::calibration
