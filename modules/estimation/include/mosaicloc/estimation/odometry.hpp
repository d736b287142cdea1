#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include <Eigen/Core>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/core/timestamp.hpp"
#include "mosaicloc/core/wheel_geometry.hpp"

namespace mosaicloc::estimation {

/// The vehicle's geometry as calibrated (differential drive, tricycle or mecanum), and its error
/// model.
struct OdometryOptions {
  core::WheelGeometry wheels;
  /// Error model (Siegwart et al., "Introduction to Autonomous Mobile Robots", 2nd ed.,
  /// section 5.2.4): each driven wheel's travel has variance k |ds|, k in mm (mm^2 per mm).
  double wheel_variance_mm = 0.01;
  /// Tricycle: the steering angle's reading error (the encoder's resolution, backlash in the
  /// steering gear), degrees, one standard deviation.
  double steering_sigma_deg = 0.05;
  /// Increments implying a faster wheel are rejected as counter glitches, m/s.
  double max_wheel_speed_mps = 15.0;
  bool Check(std::string* why) const;
};

/// Raw counter deltas to wheel travel. Counters are int32 as the PLC counts and may wrap:
/// the difference is taken modulo 2^32, which is right whenever a wheel turns less than
/// 2^31 ticks between two samples.
std::int32_t TickDelta(std::int32_t previous, std::int32_t current);

/// The covariance, in the vehicle frame (dx mm, dy mm, dtheta rad), of the motion the counts
/// leave out: travel is counted in whole ticks, so at each end of any stretch up to a tick of
/// each wheel is not counted yet. Over any distance the counted travel is off by the
/// difference of two such phases (a triangular error of variance q^2 / 6 for a tick of q mm),
/// bounded, not growing with travel: while the vehicle creeps, the counts say it stands for
/// frames at a time. Per kind: the wheels' errors through the kinematics of OdometryIncrement;
/// for a tricycle, whose steering angle is not known here, the drive wheel's error taken whole
/// along the heading and whole in the turn.
Eigen::Matrix3d TickQuantizationCovariance(const core::WheelGeometry& wheels);

/// Why an encoder sample was not used.
enum class OdometryFailure {
  kNotIncreasingTime,  ///< timestamp not after the previous sample
  kImplausibleJump,    ///< implies a wheel faster than max_wheel_speed_mps: counter glitch
};
std::string ToString(OdometryFailure failure);

/// What the encoders measured over an increment, before the kinematics turn it into motion
/// (dx, dy, dtheta) in the vehicle frame at its start: with it a filter that estimates the
/// calibration's errors c can turn it again.
///   differential: c = (k_l, k_r), each wheel's travel (1 + k) times the measured;
///     dx = (L + R) / 2, dy = 0, dtheta = (R - L) / b, b the track width;
///   tricycle: c = (k, delta), the drive wheel's travel (1 + k) times the measured and the
///     steering angle phi + delta; the fixed axle's centre moves dx = s cos(phi), dy = 0 and
///     turns dtheta = s sin(phi) / l, l the wheelbase (phi constant over the increment);
///   mecanum: c = (k, k_y), every wheel's travel (1 + k) times the measured (their common
///     radius) and the sideways motion (1 + k_y) times what the wheels imply (rollers slip when
///     they carry the vehicle sideways); with the wheels' travels fl, fr, rl, rr and
///     L = (track width + wheelbase) / 2:
///       dx = (fl + fr + rl + rr) / 4, dy = (-fl + fr + rl - rr) / 4,
///       dtheta = (-fl + fr - rl + rr) / (4 L).
struct WheelTravel {
  core::DriveKind kind = core::DriveKind::kDifferential;
  double left_mm = 0.0, right_mm = 0.0;            ///< differential; mecanum: the front wheels
  double rear_left_mm = 0.0, rear_right_mm = 0.0;  ///< mecanum
  double drive_mm = 0.0, steering_rad = 0.0;       ///< tricycle (the calibrated offset applied)
  /// Track width, wheelbase, or the mecanum L; 0: no wheel travel (the increment is a pose).
  double base_mm = 0.0;

  bool measured() const { return base_mm > 0.0; }
  /// (dx mm, dy mm, dtheta rad) with calibration errors c, and d(dx, dy, dtheta)/dc when asked.
  Eigen::Vector3d Motion(const Eigen::Vector2d& c, Eigen::Matrix<double, 3, 2>* jacobian = nullptr) const;
  /// d(dx, dy, dtheta)/d(what the encoders measure), at c = 0: the columns are the left and
  /// right wheels' travels (differential), the four wheels' (mecanum: left, right, rear left,
  /// rear right) or the drive wheel's travel and the steering angle (tricycle); unused ones 0.
  Eigen::Matrix<double, 3, 4> InputJacobian() const;
  /// The share `fraction` of it: the travels scaled, the steering angle the same.
  WheelTravel Part(double fraction) const;
  /// How far the wheel behind each calibration state rolled, mm: what its random walk grows
  /// with (mecanum: the wheels' mean travel and the sideways motion).
  Eigen::Vector2d Rolled() const;
};

/// Motion between two encoder samples, in the vehicle frame at the first.
struct OdometryIncrement {
  core::Duration dt{};
  WheelTravel travel;
  core::Pose2 previous_from_current;  ///< exact arc of constant curvature
  double forward_speed_mps = 0.0;
  double lateral_speed_mps = 0.0;  ///< to the left; 0 but for a mecanum vehicle
  double yaw_rate_radps = 0.0;
  /// Covariance of previous_from_current (x mm, y mm, yaw rad) in the previous vehicle frame,
  /// from the wheel error model.
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
};

/// Dead reckoning from wheel encoders: integrates world_from_vehicle and its covariance
/// (x mm, y mm, yaw rad). The first sample only initialises the counters.
class WheelOdometry {
 public:
  /// Throws core::Error (invalid input) when the options fail Check().
  explicit WheelOdometry(const OdometryOptions& options,
                         const core::Pose2& world_from_vehicle = core::Pose2::Identity());

  /// Feeds one reading of the counters (the kind's). On failure the state is unchanged,
  /// and the sample is kept as the new counter reference only after a glitch (so one bad
  /// sample costs one step).
  core::Result<OdometryIncrement, OdometryFailure> Update(core::Timestamp time, const core::EncoderCounts& counts);

  const core::Pose2& world_from_vehicle() const { return world_from_vehicle_; }
  const Eigen::Matrix3d& covariance() const { return covariance_; }
  std::optional<core::Timestamp> last_time() const { return last_time_; }
  /// Restarts integration from a pose (e.g. a fix); the counters are kept.
  void Reset(const core::Pose2& world_from_vehicle, const Eigen::Matrix3d& covariance);
  /// The next sample only re-seeds the counters: for after an outage, when the wheels may
  /// have turned unseen or the PLC restarted and reset its counters.
  void ForgetCounters() { last_time_.reset(); }

  /// Wheel travel in mm for a tick count.
  double LeftTicksToMm(std::int64_t ticks) const;
  double RightTicksToMm(std::int64_t ticks) const;

 private:
  OdometryOptions options_;
  core::Pose2 world_from_vehicle_;
  Eigen::Matrix3d covariance_ = Eigen::Matrix3d::Zero();
  std::optional<core::Timestamp> last_time_;
  core::EncoderCounts last_;
};

}  // namespace mosaicloc::estimation
