#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/core/wheel_geometry.hpp"

namespace mosaicloc::calibration {

/// What the encoders said of the wheels between two samples, by the vehicle's kind: how far
/// each wheel turned (differential), or how far the drive wheel turned and the steering angle
/// as its encoder read it over the interval, before the calibrated offset is added (tricycle).
struct WheelTurn {
  double left_wheel_rad = 0.0;
  double right_wheel_rad = 0.0;
  double drive_wheel_rad = 0.0;
  double steering_rad = 0.0;
};

/// One step of a calibration drive, between two frames: what the wheels did over each
/// encoder interval between them, in order (one for neighbouring frames), and how the camera
/// moved (registration of the two ideal images). The vehicle's motion is the composition of
/// the intervals' arcs, so the path between two frames further apart (a longer baseline)
/// need not be one arc.
struct DriveStep {
  std::vector<WheelTurn> arcs;
  core::Pose2 previous_from_current_camera;  ///< camera floor frame C, mm and rad
};

/// How far a wheel turn moves the vehicle's origin along its arc and how far it turns it
/// (d mm, theta rad; the model below), for the kind's three wheel parameters in the order of
/// VehicleCalibrationResult::sigma: (r_l, r_r, b) or (r, l, steering offset in rad).
Eigen::Vector2d ArcLengthAndTurn(const WheelTurn& turn, core::DriveKind kind, const Eigen::Vector3d& wheels);

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
  core::WheelGeometry wheels;  ///< the initial wheels with the kind's calibrated values
  /// One-sigma uncertainties from the residuals (covariance s^2 (J^T J)^-1, s^2 the
  /// residual variance per degree of freedom): x_mm, y_mm, yaw_rad of vehicle_from_camera,
  /// then the kind's three: left radius, right radius, track width (mm); or the drive wheel's
  /// radius, the wheelbase (mm) and the steering offset (rad).
  Eigen::Matrix<double, 6, 1> sigma = Eigen::Matrix<double, 6, 1>::Zero();
  double rms_translation_mm = 0.0;  ///< per-step registration residuals after the fit
  double rms_rotation_rad = 0.0;
  int steps = 0;
};

/// Camera mounting and wheel geometry from a calibration drive: a straight run (its
/// direction in the camera frame gives the mounting yaw, its length the wheel radii; a
/// tricycle's steering reading on it, the steering offset) and a turn in place (the camera's
/// circle around the axle centre gives the lever arm, the angle turned the track width; a
/// tricycle pivots about its fixed axle with the steered wheel across, which gives the
/// wheelbase).
///
/// Model: a differential drive's wheel arcs d_l = r_l phi_l, d_r = r_r phi_r move the vehicle
/// along a circular arc of length d = (d_l + d_r)/2 turning by theta = (d_r - d_l)/b (Siegwart
/// & Nourbakhsh, "Introduction to Autonomous Mobile Robots", section 5.2.4); a tricycle's drive
/// wheel arc d_w = r phi_w at steering angle psi = psi_read + offset moves its axle centre
/// d = d_w cos(psi), turning by theta = d_w sin(psi) / l (l the wheelbase). Either way
///   A_V = (d sin(theta)/theta, d (1 - cos(theta))/theta, theta),
/// and the camera, rigidly mounted at X = vehicle_from_camera, moves by
///   A_C = X^-1 A_V X        (the SE(2) hand-eye equation AX = XB).
/// The residual of a step is Log(A_C_predicted^-1 A_C_measured), translation divided by
/// registration_sigma_mm and rotation by registration_sigma_rad; Levenberg-Marquardt
/// minimises their sum of squares over X and the kind's three: (r_l, r_r, b) or (r, l, offset).
/// Never throws for data that does not constrain the solution: the result says so.
VehicleCalibrationResult CalibrateVehicle(const std::vector<DriveStep>& steps, const VehicleCalibrationOptions& options);

}  // namespace mosaicloc::calibration
