#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/core/wheel_geometry.hpp"

namespace mosaicloc::calibration {

/// How far each wheel turned between two encoder samples, rad.
struct WheelTurn {
  double left_wheel_rad = 0.0;
  double right_wheel_rad = 0.0;
};

/// One step of a calibration drive, between two frames: how far each wheel turned (from the
/// encoder ticks) and how the camera moved (registration of the two ideal images).
struct DriveStep {
  double left_wheel_rad = 0.0;
  double right_wheel_rad = 0.0;
  core::Pose2 previous_from_current_camera;  ///< camera floor frame C, mm and rad
  /// For two frames further apart (a longer baseline): the wheel turns of each interval
  /// between them, in order. The vehicle's motion is then the composition of their arcs, so
  /// the path between the frames need not be one arc; left_wheel_rad and right_wheel_rad
  /// are ignored.
  std::vector<WheelTurn> arcs;
};

struct VehicleCalibrationOptions {
  /// Where the solver starts (the nominal, as-designed values).
  core::WheelGeometry initial_wheels;
  core::Pose2 initial_vehicle_from_camera;
  /// Standard deviations of one registration, for weighting translation against rotation.
  double registration_sigma_mm = 0.02;
  double registration_sigma_rad = 1e-4;
  int max_iterations = 50;
  /// How many of the steps are independent, when they are not (several baselines per frame
  /// share its registration noise): the uncertainty is scaled to this many steps. 0 = all.
  int independent_steps = 0;
  bool Check(std::string* why) const;
};

struct VehicleCalibrationResult {
  bool converged = false;
  std::string message;  ///< why not, when not converged
  int iterations = 0;
  core::Pose2 vehicle_from_camera;
  core::WheelGeometry wheels;
  /// One-sigma uncertainties from the residuals (covariance s^2 (J^T J)^-1, s^2 the
  /// residual variance per degree of freedom): x_mm, y_mm, yaw_rad of vehicle_from_camera,
  /// then left radius, right radius, track width (mm).
  Eigen::Matrix<double, 6, 1> sigma = Eigen::Matrix<double, 6, 1>::Zero();
  double rms_translation_mm = 0.0;  ///< per-step registration residuals after the fit
  double rms_rotation_rad = 0.0;
  int steps = 0;
};

/// Camera mounting and wheel geometry from a calibration drive: a straight run (its
/// direction in the camera frame gives the mounting yaw, its length the wheel radii) and a
/// turn in place (the camera's circle around the axle centre gives the lever arm, the angle
/// turned the track width).
///
/// Model: a step's wheel arcs d_l = r_l phi_l, d_r = r_r phi_r move the vehicle along a
/// circular arc of length d = (d_l + d_r)/2 turning by theta = (d_r - d_l)/b (Siegwart &
/// Nourbakhsh, "Introduction to Autonomous Mobile Robots", section 5.2.4):
///   A_V = (d sin(theta)/theta, d (1 - cos(theta))/theta, theta),
/// and the camera, rigidly mounted at X = vehicle_from_camera, moves by
///   A_C = X^-1 A_V X        (the SE(2) hand-eye equation AX = XB).
/// The residual of a step is Log(A_C_predicted^-1 A_C_measured), translation divided by
/// registration_sigma_mm and rotation by registration_sigma_rad; Levenberg-Marquardt
/// minimises their sum of squares over (X, r_l, r_r, b).
/// Never throws for data that does not constrain the solution: the result says so.
VehicleCalibrationResult CalibrateVehicle(const std::vector<DriveStep>& steps, const VehicleCalibrationOptions& options);

}  // namespace mosaicloc::calibration
