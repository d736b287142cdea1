#include "mosaicloc/estimation/odometry.hpp"

#include <cmath>
#include <numbers>

namespace mosaicloc::estimation {

bool DiffDriveOptions::Check(std::string* why) const {
  if (!wheels.Check(why)) return false;
  if (!(wheel_variance_mm >= 0.0) || !(max_wheel_speed_mps > 0.0)) {
    *why = "wheel_variance_mm must be >= 0 and max_wheel_speed_mps > 0";
    return false;
  }
  return true;
}

std::int32_t TickDelta(std::int32_t previous, std::int32_t current) {
  const std::uint32_t difference = static_cast<std::uint32_t>(current) - static_cast<std::uint32_t>(previous);
  return static_cast<std::int32_t>(difference);  // two's complement: modular since C++20
}

std::string ToString(OdometryFailure failure) {
  switch (failure) {
    case OdometryFailure::kNotIncreasingTime: return "encoder timestamp not increasing";
    case OdometryFailure::kImplausibleJump: return "encoder counter jump faster than max_wheel_speed_mps";
  }
  return "unknown";
}

DiffDriveOdometry::DiffDriveOdometry(const DiffDriveOptions& options, const core::Pose2& world_from_vehicle)
    : options_(options), world_from_vehicle_(world_from_vehicle) {
  std::string why;
  if (!options_.Check(&why)) core::ThrowInvalidInput("odometry: " + why);
}

double DiffDriveOdometry::LeftTicksToMm(std::int64_t ticks) const {
  return 2.0 * std::numbers::pi * options_.wheels.left_wheel_radius_mm * static_cast<double>(ticks) /
         static_cast<double>(options_.wheels.ticks_per_revolution);
}

double DiffDriveOdometry::RightTicksToMm(std::int64_t ticks) const {
  return 2.0 * std::numbers::pi * options_.wheels.right_wheel_radius_mm * static_cast<double>(ticks) /
         static_cast<double>(options_.wheels.ticks_per_revolution);
}

void DiffDriveOdometry::Reset(const core::Pose2& world_from_vehicle, const Eigen::Matrix3d& covariance) {
  world_from_vehicle_ = world_from_vehicle;
  covariance_ = covariance;
}

core::Result<OdometryIncrement, OdometryFailure> DiffDriveOdometry::Update(core::Timestamp time,
                                                                          std::int32_t left_ticks,
                                                                          std::int32_t right_ticks) {
  if (!last_time_) {
    last_time_ = time;
    last_left_ = left_ticks;
    last_right_ = right_ticks;
    return OdometryIncrement{};
  }
  if (time <= *last_time_) return core::Fail(OdometryFailure::kNotIncreasingTime);

  OdometryIncrement increment;
  increment.dt = time - *last_time_;
  increment.left_mm = LeftTicksToMm(TickDelta(last_left_, left_ticks));
  increment.right_mm = RightTicksToMm(TickDelta(last_right_, right_ticks));
  last_time_ = time;
  last_left_ = left_ticks;
  last_right_ = right_ticks;

  const double dt_s = core::ToSeconds(increment.dt);
  const double max_travel_mm = options_.max_wheel_speed_mps * 1000.0 * dt_s;
  if (std::abs(increment.left_mm) > max_travel_mm || std::abs(increment.right_mm) > max_travel_mm) {
    return core::Fail(OdometryFailure::kImplausibleJump);
  }

  const double b = options_.wheels.track_width_mm;
  increment.track_width_mm = b;
  const double ds = 0.5 * (increment.right_mm + increment.left_mm);
  const double dtheta = (increment.right_mm - increment.left_mm) / b;
  increment.previous_from_current = core::Pose2::Exp({ds, 0.0, dtheta});
  increment.forward_speed_mps = ds / dt_s * 1e-3;
  increment.yaw_rate_radps = dtheta / dt_s;

  // Covariance propagation with the midpoint model (Siegwart et al., eqs. 5.6-5.9):
  //   x' = x + ds cos(phi), y' = y + ds sin(phi), theta' = theta + dtheta, phi = theta + dtheta/2,
  //   P' = Fp P Fp^T + Frl diag(k|ds_r|, k|ds_l|) Frl^T.
  const double phi = world_from_vehicle_.yaw_rad() + 0.5 * dtheta;
  const double c = std::cos(phi);
  const double s = std::sin(phi);
  Eigen::Matrix3d f_pose = Eigen::Matrix3d::Identity();
  f_pose(0, 2) = -ds * s;
  f_pose(1, 2) = ds * c;
  Eigen::Matrix<double, 3, 2> f_wheels;  // columns: right, left
  f_wheels << 0.5 * c - ds / (2.0 * b) * s, 0.5 * c + ds / (2.0 * b) * s,
              0.5 * s + ds / (2.0 * b) * c, 0.5 * s - ds / (2.0 * b) * c,
              1.0 / b, -1.0 / b;
  const Eigen::Vector2d wheel_variance(options_.wheel_variance_mm * std::abs(increment.right_mm),
                                       options_.wheel_variance_mm * std::abs(increment.left_mm));
  const Eigen::Matrix3d wheel_part = f_wheels * wheel_variance.asDiagonal() * f_wheels.transpose();
  covariance_ = f_pose * covariance_ * f_pose.transpose() + wheel_part;
  // The same in the previous vehicle frame: rotate the world-frame part back by its yaw.
  Eigen::Matrix3d to_vehicle = Eigen::Matrix3d::Identity();
  to_vehicle.topLeftCorner<2, 2>() = world_from_vehicle_.Rotation().transpose();
  increment.covariance = to_vehicle * wheel_part * to_vehicle.transpose();
  world_from_vehicle_ = world_from_vehicle_ * increment.previous_from_current;
  return increment;
}

}  // namespace mosaicloc::estimation
