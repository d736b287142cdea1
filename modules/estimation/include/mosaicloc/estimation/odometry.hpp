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

/// Differential-drive geometry as calibrated, and its error model.
struct DiffDriveOptions {
  core::WheelGeometry wheels;
  /// Error model (Siegwart et al., "Introduction to Autonomous Mobile Robots", 2nd ed.,
  /// section 5.2.4): each wheel's travel has variance k |ds|, k in mm (mm^2 per mm).
  double wheel_variance_mm = 0.01;
  /// Increments implying a faster wheel are rejected as counter glitches, m/s.
  double max_wheel_speed_mps = 15.0;
  bool Check(std::string* why) const;
};

/// Raw counter deltas to wheel travel. Counters are int32 as the PLC counts and may wrap:
/// the difference is taken modulo 2^32, which is right whenever a wheel turns less than
/// 2^31 ticks between two samples.
std::int32_t TickDelta(std::int32_t previous, std::int32_t current);

/// Why an encoder sample was not used.
enum class OdometryFailure {
  kNotIncreasingTime,  ///< timestamp not after the previous sample
  kImplausibleJump,    ///< implies a wheel faster than max_wheel_speed_mps: counter glitch
};
std::string ToString(OdometryFailure failure);

/// Motion between two encoder samples, in the vehicle frame at the first.
struct OdometryIncrement {
  core::Duration dt{};
  double left_mm = 0.0;
  double right_mm = 0.0;
  /// The track width the travels were turned into motion with: with it a filter that
  /// estimates the wheels' scale errors can turn them again.
  double track_width_mm = 0.0;
  core::Pose2 previous_from_current;  ///< exact arc of constant curvature
  double forward_speed_mps = 0.0;
  double yaw_rate_radps = 0.0;
  /// Covariance of previous_from_current (x mm, y mm, yaw rad) in the previous vehicle frame,
  /// from the wheel error model.
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
};

/// Dead reckoning from wheel encoders: integrates world_from_vehicle and its covariance
/// (x mm, y mm, yaw rad). The first sample only initialises the counters.
class DiffDriveOdometry {
 public:
  /// Throws core::Error (invalid input) when the options fail Check().
  explicit DiffDriveOdometry(const DiffDriveOptions& options,
                             const core::Pose2& world_from_vehicle = core::Pose2::Identity());

  /// Feeds one encoder sample. On failure the state is unchanged, and the sample is kept
  /// as the new counter reference only after a glitch (so one bad sample costs one step).
  core::Result<OdometryIncrement, OdometryFailure> Update(core::Timestamp time, std::int32_t left_ticks,
                                                          std::int32_t right_ticks);

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
  DiffDriveOptions options_;
  core::Pose2 world_from_vehicle_;
  Eigen::Matrix3d covariance_ = Eigen::Matrix3d::Zero();
  std::optional<core::Timestamp> last_time_;
  std::int32_t last_left_ = 0;
  std::int32_t last_right_ = 0;
};

}  // namespace mosaicloc::estimation
