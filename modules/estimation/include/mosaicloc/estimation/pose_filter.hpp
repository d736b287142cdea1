#pragma once

#include <cmath>
#include <deque>
#include <string>

#include <Eigen/Core>

#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/core/timestamp.hpp"
#include "mosaicloc/estimation/odometry.hpp"

namespace mosaicloc::estimation {

struct PoseFilterOptions {
  /// Fixes whose squared Mahalanobis distance to the prediction exceeds this are rejected
  /// (chi-square, 3 degrees of freedom: 16.27 is the 99.9 % quantile).
  double gate_chi2 = 16.27;
  /// How far back a late fix may be applied.
  core::Duration history = std::chrono::seconds(2);
  /// Extra variance per second when the pose is extrapolated past the last odometry
  /// sample (the system model's constant-velocity assumption), mm^2/s and rad^2/s.
  double extrapolation_position_variance_mm2_per_s = 1.0;
  double extrapolation_yaw_variance_rad2_per_s = 1e-5;
  /// Coasting without odometry (Coast): the vehicle may accelerate this much, so the pose
  /// after T seconds is uncertain by a T^2 / 2 (and the heading by alpha T^2 / 2).
  double coast_acceleration_mps2 = 1.0;
  double coast_yaw_acceleration_radps2 = 0.5;
  /// The system model's velocities are the odometry's over the increments of this long (at
  /// least the newest): one increment spans the difference of two time stamps each a little
  /// uncertain, and its speed alone can be far off.
  core::Duration speed_window = std::chrono::milliseconds(40);
  /// Each wheel's scale error (true travel = (1 + k) x calibrated travel) is part of the
  /// state: its standard deviation at the start (0: the calibration is taken as exact, and k
  /// stays 0), and how fast it may wander (tyre wear, load), per square root of a metre.
  double wheel_scale_sigma = 0.03;
  double wheel_scale_walk_per_sqrt_m = 0.001;
  /// What the second calibration state is: the right wheel's scale error (differential), the
  /// steering angle's offset error (tricycle; the first is then the drive wheel's scale), or
  /// the sideways motion's scale error (mecanum; the first is then the four wheels' scale).
  core::DriveKind kind = core::DriveKind::kDifferential;
  /// Mecanum: the sideways scale error's standard deviation at the start (rollers slip by a
  /// few per cent when they carry the vehicle sideways); it wanders as the wheel scale does.
  double lateral_scale_sigma = 0.1;
  /// Tricycle: the steering offset error's standard deviation at the start, and its wander
  /// per square root of a metre driven (wear of the steering gear, a knock).
  double steering_offset_sigma_deg = 1.0;
  double steering_offset_walk_deg_per_sqrt_m = 0.01;
  bool Check(std::string* why) const;
};

/// The latest state and the velocities the system model extrapolates it with: enough for
/// another thread to answer "where is the vehicle now" without touching the filter.
struct MotionState {
  core::Timestamp time;
  core::Pose2 world_from_vehicle;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  double forward_speed_mm_per_s = 0.0;
  double yaw_rate_rad_per_s = 0.0;
  double lateral_speed_mm_per_s = 0.0;  ///< to the left; 0 but for a mecanum vehicle
  /// (forward, lateral, yaw rate): the body twist per second.
  Eigen::Vector3d Twist() const;
  /// How fast the vehicle frame's origin moves, mm/s.
  double speed_mm_per_s() const { return std::hypot(forward_speed_mm_per_s, lateral_speed_mm_per_s); }
  /// The pose at `at` moving on with the constant twist (also before `time`).
  core::Pose2 PoseAt(core::Timestamp at) const;
};

/// Outcome of one fix.
struct FixOutcome {
  bool accepted = false;
  double mahalanobis2 = 0.0;  ///< squared Mahalanobis distance of the fix to the prediction
  /// The fix minus the prediction at its time (x mm, y mm, yaw rad) and that difference's
  /// predicted covariance S (prediction plus fix): the innovation whose consistency with S a
  /// report checks. Zero when the fix was refused for its time.
  Eigen::Vector3d innovation = Eigen::Vector3d::Zero();
  Eigen::Matrix3d innovation_covariance = Eigen::Matrix3d::Zero();
  std::string reason;         ///< why it was rejected; empty when accepted
};

/// Extended Kalman filter on world_from_vehicle (x mm, y mm, yaw rad) and two calibration
/// errors c of the wheels (differential: the two wheels' scale errors (k_l, k_r); tricycle: the
/// drive wheel's scale error and the steering offset's error (k, delta rad); mecanum: the
/// wheels' common scale error and the sideways motion's (k, k_y); WheelTravel),
/// driven by wheel odometry as its control input and corrected by absolute fixes that may
/// arrive late.
///
/// Why odometry as the input rather than a (x, y, yaw, v, omega) state with odometry as a
/// measurement: encoders measure the motion itself at 100 Hz or more, so integrating them
/// loses nothing and needs no motion prior that an accelerating AGV would violate; the
/// velocities the system model needs for extrapolation come from the latest increment.
/// Why the wheel scales: a wheel radius off by 2 % puts the prediction 4.8 mm off after a
/// frame at 7.2 m/s, far more than the wheels' random error, and turns the heading wherever
/// the two wheels differ. Fixes every frame make both scales observable within a few frames
/// (Martinelli et al., "Simultaneous localization and odometry self calibration for mobile
/// robot", Autonomous Robots 22, 2007, do the same with a laser), and the prediction is then
/// as good as the wheels' random error allows.
///
/// Prediction, with the wheels' measured travel m (WheelTravel: for a differential drive the
/// travels l, r and b the track width, L = (1 + k_l) l, R = (1 + k_r) r, ds = (L + R) / 2,
/// dtheta = (R - L) / b; for a tricycle ds = s cos(phi), dtheta = s sin(phi) / l):
///   d = Exp(ds(m, c), 0, dtheta(m, c)),  x+ = x (+) d,  P+ = F P F^T + G Q G^T + W,
/// F the Jacobian in pose and calibration, Q the wheel error model's covariance of d,
/// G = diag(R(t), 1), and W the calibration's random walk (variance walk^2 per metre its wheel
/// rolled).
/// Correction by a fix z of the pose with covariance R (h(x) = pose, yaw residual wrapped):
///   S = P_pp + R, K = P H^T S^-1, x+ = x + K (z - h(x)), P+ = (I - K H) P (I - K H)^T + K R K^T.
/// A late fix (its time inside the history) is applied at its own time: the increment that
/// spans it is split along its arc, the state there corrected, and the later wheel travels
/// replayed on top with the corrected scales.
class PoseFilter {
 public:
  /// Throws core::Error (invalid input) when options fail Check().
  PoseFilter(const PoseFilterOptions& options, core::Timestamp time, const core::Pose2& world_from_vehicle,
             const Eigen::Matrix3d& covariance);

  /// Moves the state to `time` by an odometry increment (which ends at `time`). If the state
  /// has coasted past the increment's start, only the rest of the increment is applied.
  void Predict(core::Timestamp time, const OdometryIncrement& increment);
  /// Moves the state to `time` on the system model alone (constant velocity, covariance
  /// grown by the extrapolation variances): for a frame newer than the latest odometry, so
  /// its fix can still be applied at its own time.
  void Coast(core::Timestamp time);
  /// Applies a fix of world_from_vehicle at `time` (not after the latest odometry, not before
  /// the history). `prediction_spread` is extra uncertainty of the state at that time that
  /// the odometry model does not carry (e.g. its time-stamp error), added before the update.
  /// Never throws: a rejected fix says why.
  FixOutcome Correct(core::Timestamp time, const core::Pose2& world_from_vehicle, const Eigen::Matrix3d& covariance,
                     const Eigen::Matrix3d& prediction_spread = Eigen::Matrix3d::Zero());
  /// The covariance of the pose at `time` that Correct with these covariances would leave,
  /// P (P + R)^-1 R: a confident prediction keeps its certainty whatever the fix, an
  /// uncertain one takes the fix's.
  Eigen::Matrix3d CorrectedCovariance(core::Timestamp time, const Eigen::Matrix3d& covariance,
                                      const Eigen::Matrix3d& prediction_spread = Eigen::Matrix3d::Zero()) const;
  /// Restarts from a pose, dropping the history. The wheel scale estimates and their
  /// variances are kept: they belong to the vehicle.
  void Reset(core::Timestamp time, const core::Pose2& world_from_vehicle, const Eigen::Matrix3d& covariance);
  /// Restarts from a pose known at `time` (a relocalized frame's): the odometry after `time`
  /// is kept and replayed on it, so the next frames still find their time in the history;
  /// the states before it are dropped. A time after the history is a Reset there.
  void RestartAt(core::Timestamp time, const core::Pose2& world_from_vehicle, const Eigen::Matrix3d& covariance);

  /// The system model: the pose at any time, interpolated along the odometry inside the
  /// history, extrapolated with the latest linear and angular velocity after it.
  core::Pose2 PoseAt(core::Timestamp time) const;
  Eigen::Matrix3d CovarianceAt(core::Timestamp time) const;

  core::Timestamp time() const { return history_.back().time; }
  MotionState Latest() const;
  const core::Pose2& world_from_vehicle() const { return history_.back().world_from_vehicle; }
  /// Covariance of the latest pose (x mm, y mm, yaw rad).
  Eigen::Matrix3d covariance() const { return history_.back().covariance.topLeftCorner<3, 3>(); }
  /// The estimated calibration errors c (differential: the wheels' scale errors (k_l, k_r);
  /// tricycle: the drive wheel's scale error and the steering offset's error in radians;
  /// mecanum: the wheels' and the sideways motion's scale errors) and their covariance.
  const Eigen::Vector2d& wheel_scale_error() const { return history_.back().wheel_scale; }
  Eigen::Matrix2d wheel_scale_covariance() const { return history_.back().covariance.bottomRightCorner<2, 2>(); }

 private:
  using Matrix5d = Eigen::Matrix<double, 5, 5>;
  struct Node {
    core::Timestamp time;
    core::Pose2 world_from_vehicle;
    Eigen::Vector2d wheel_scale = Eigen::Vector2d::Zero();  ///< the calibration errors c
    Matrix5d covariance = Matrix5d::Zero();                  ///< of (x, y, yaw, c)
    // The motion from the previous node: wheel travel as measured (the pose increment follows
    // from it and c), or, when coasting (travel not measured), a fixed pose increment.
    WheelTravel travel;
    core::Pose2 increment;                  ///< from the previous node to this one, as applied
    Eigen::Matrix3d increment_covariance = Eigen::Matrix3d::Zero();  ///< in the previous vehicle frame
  };
  // The node's share `fraction` of its motion (an arc of constant curvature, its variance
  // growing with travel), from the same start.
  static Node Part(const Node& node, double fraction);
  // The calibration states' standard deviations at the start and random walks per sqrt(m).
  Eigen::Vector2d CalibrationSigma() const;
  Eigen::Vector2d CalibrationWalk() const;
  void Propagate(const Node& from, Node* to) const;
  // Index of the last node at or before `time` (history_ is never empty).
  std::size_t NodeBefore(core::Timestamp time) const;
  void Prune();
  // The history cut at `time`: node k at or before it, the state at `time` (node k itself,
  // or a part of the next increment), and the nodes after it with the spanning increment cut.
  struct Split {
    std::size_t k = 0;
    Node at;
    std::deque<Node> later;
    bool split = false;  ///< `at` is a new node between k and k + 1
  };
  Split SplitAt(core::Timestamp time) const;
  // Replaces the history from the split on by `at` and the later nodes propagated from it.
  void Replay(Split split);

  PoseFilterOptions options_;
  std::deque<Node> history_;
  double forward_speed_mm_per_s_ = 0.0;
  double lateral_speed_mm_per_s_ = 0.0;
  double yaw_rate_rad_per_s_ = 0.0;
  core::Timestamp last_odometry_;  ///< of the latest node made from odometry (or a reset)
  // The newest odometry increments' motion (wheel scales applied) and spans, for the speeds.
  struct Recent {
    core::Timestamp end;
    core::Duration dt{};
    Eigen::Vector3d motion;
  };
  std::deque<Recent> recent_;
};

}  // namespace mosaicloc::estimation
