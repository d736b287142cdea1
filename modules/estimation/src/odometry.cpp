#include "mosaicloc/estimation/odometry.hpp"

#include <cmath>
#include <numbers>

namespace mosaicloc::estimation {

bool OdometryOptions::Check(std::string* why) const {
  if (!wheels.Check(why)) return false;
  if (!(wheel_variance_mm >= 0.0) || !(max_wheel_speed_mps > 0.0)) {
    *why = "wheel_variance_mm must be >= 0 and max_wheel_speed_mps > 0";
    return false;
  }
  if (!(steering_sigma_deg >= 0.0 && steering_sigma_deg <= 10.0)) {
    *why = "steering_sigma_deg must be in [0, 10]";
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

Eigen::Vector3d WheelTravel::Motion(const Eigen::Vector2d& c, Eigen::Matrix<double, 3, 2>* jacobian) const {
  if (kind == core::DriveKind::kTricycle) {
    const double s = (1.0 + c.x()) * drive_mm;
    const double phi = steering_rad + c.y();
    const double cos_phi = std::cos(phi), sin_phi = std::sin(phi);
    if (jacobian != nullptr) {  // columns k, delta; rows dx, dy, dtheta
      *jacobian << drive_mm * cos_phi, -s * sin_phi, 0.0, 0.0, drive_mm * sin_phi / base_mm, s * cos_phi / base_mm;
    }
    return {s * cos_phi, 0.0, s * sin_phi / base_mm};
  }
  if (kind == core::DriveKind::kMecanum) {
    const double forward = 0.25 * (left_mm + right_mm + rear_left_mm + rear_right_mm);
    const double sideways = 0.25 * (-left_mm + right_mm + rear_left_mm - rear_right_mm);
    const double turn = 0.25 * (-left_mm + right_mm - rear_left_mm + rear_right_mm) / base_mm;
    const double scale = 1.0 + c.x(), sideways_scale = 1.0 + c.y();
    if (jacobian != nullptr) {  // columns k, k_y
      *jacobian << forward, 0.0, sideways_scale * sideways, scale * sideways, turn, 0.0;
    }
    return {scale * forward, scale * sideways_scale * sideways, scale * turn};
  }
  const double left = (1.0 + c.x()) * left_mm;
  const double right = (1.0 + c.y()) * right_mm;
  if (jacobian != nullptr) {  // columns k_l, k_r: dk_l moves dx by l/2 and dtheta by -l/b
    *jacobian << 0.5 * left_mm, 0.5 * right_mm, 0.0, 0.0, -left_mm / base_mm, right_mm / base_mm;
  }
  return {0.5 * (left + right), 0.0, (right - left) / base_mm};
}

Eigen::Matrix<double, 3, 4> WheelTravel::InputJacobian() const {
  Eigen::Matrix<double, 3, 4> d_motion = Eigen::Matrix<double, 3, 4>::Zero();
  const double l = base_mm;
  if (kind == core::DriveKind::kTricycle) {
    const double cos_phi = std::cos(steering_rad), sin_phi = std::sin(steering_rad), s = drive_mm;
    d_motion.leftCols<2>() << cos_phi, -s * sin_phi, 0.0, 0.0, sin_phi / l, s * cos_phi / l;
  } else if (kind == core::DriveKind::kMecanum) {
    d_motion << 0.25, 0.25, 0.25, 0.25, -0.25, 0.25, 0.25, -0.25, -0.25 / l, 0.25 / l, -0.25 / l, 0.25 / l;
  } else {
    d_motion.leftCols<2>() << 0.5, 0.5, 0.0, 0.0, -1.0 / l, 1.0 / l;
  }
  return d_motion;
}

WheelTravel WheelTravel::Part(double fraction) const {
  WheelTravel part = *this;
  part.left_mm *= fraction;
  part.right_mm *= fraction;
  part.rear_left_mm *= fraction;
  part.rear_right_mm *= fraction;
  part.drive_mm *= fraction;
  return part;
}

Eigen::Vector2d WheelTravel::Rolled() const {
  if (kind == core::DriveKind::kTricycle) return {std::abs(drive_mm), std::abs(drive_mm)};
  if (kind == core::DriveKind::kMecanum) {
    return {0.25 * (std::abs(left_mm) + std::abs(right_mm) + std::abs(rear_left_mm) + std::abs(rear_right_mm)),
            0.25 * std::abs(-left_mm + right_mm + rear_left_mm - rear_right_mm)};
  }
  return {std::abs(left_mm), std::abs(right_mm)};
}

WheelOdometry::WheelOdometry(const OdometryOptions& options, const core::Pose2& world_from_vehicle)
    : options_(options), world_from_vehicle_(world_from_vehicle) {
  std::string why;
  if (!options_.Check(&why)) core::ThrowInvalidInput("odometry: " + why);
}

Eigen::Matrix3d TickQuantizationCovariance(const core::WheelGeometry& wheels) {
  const auto tick_variance = [&wheels](double radius_mm) {
    const double q = wheels.TicksToMm(radius_mm, 1);
    return q * q / 6.0;
  };
  if (wheels.kind == core::DriveKind::kTricycle) {
    const double v = tick_variance(wheels.drive_wheel_radius_mm), l = wheels.wheelbase_mm;
    return Eigen::Vector3d(v, 0.0, v / (l * l)).asDiagonal();
  }
  // Through the kinematics the odometry turns the wheels' travels with.
  WheelTravel travel;
  travel.kind = wheels.kind;
  Eigen::Vector4d variance = Eigen::Vector4d::Zero();
  if (wheels.kind == core::DriveKind::kMecanum) {
    travel.base_mm = 0.5 * (wheels.track_width_mm + wheels.wheelbase_mm);
    variance.setConstant(tick_variance(wheels.mecanum_wheel_radius_mm));
  } else {
    travel.base_mm = wheels.track_width_mm;
    variance.head<2>() << tick_variance(wheels.left_wheel_radius_mm), tick_variance(wheels.right_wheel_radius_mm);
  }
  const Eigen::Matrix<double, 3, 4> d_motion = travel.InputJacobian();
  return d_motion * variance.asDiagonal() * d_motion.transpose();
}

double WheelOdometry::LeftTicksToMm(std::int64_t ticks) const {
  return options_.wheels.TicksToMm(options_.wheels.left_wheel_radius_mm, ticks);
}

double WheelOdometry::RightTicksToMm(std::int64_t ticks) const {
  return options_.wheels.TicksToMm(options_.wheels.right_wheel_radius_mm, ticks);
}

void WheelOdometry::Reset(const core::Pose2& world_from_vehicle, const Eigen::Matrix3d& covariance) {
  world_from_vehicle_ = world_from_vehicle;
  covariance_ = covariance;
}

core::Result<OdometryIncrement, OdometryFailure> WheelOdometry::Update(core::Timestamp time,
                                                                      const core::EncoderCounts& counts) {
  if (!last_time_) {
    last_time_ = time;
    last_ = counts;
    return OdometryIncrement{};
  }
  if (time <= *last_time_) return core::Fail(OdometryFailure::kNotIncreasingTime);

  const core::WheelGeometry& wheels = options_.wheels;
  OdometryIncrement increment;
  increment.dt = time - *last_time_;
  WheelTravel& travel = increment.travel;
  travel.kind = wheels.kind;
  // The measured inputs' variances (up to four: wheel travels or a steering angle, in the
  // order of WheelTravel::InputJacobian); unused inputs have variance 0.
  Eigen::Vector4d variance = Eigen::Vector4d::Zero();
  double fastest_mm = 0.0;
  const double k = options_.wheel_variance_mm;
  if (wheels.kind == core::DriveKind::kTricycle) {
    travel.base_mm = wheels.wheelbase_mm;
    travel.drive_mm = wheels.TicksToMm(wheels.drive_wheel_radius_mm, TickDelta(last_.drive_ticks, counts.drive_ticks));
    // The angle held over the increment: the mean of its two readings. How it moved between
    // them is not known: a change of d between the readings adds the variance of a uniform
    // spread over d (d^2 / 12), which at the entry to a bend (the wheel swung within a sample)
    // far exceeds the reading's own error.
    const double before = wheels.SteeringRad(last_.steering_ticks), after = wheels.SteeringRad(counts.steering_ticks);
    travel.steering_rad = 0.5 * (before + after);
    fastest_mm = std::abs(travel.drive_mm);
    const double sigma_rad = options_.steering_sigma_deg * std::numbers::pi / 180.0;
    variance.head<2>() = Eigen::Vector2d(k * std::abs(travel.drive_mm),
                                         sigma_rad * sigma_rad + (after - before) * (after - before) / 12.0);
  } else if (wheels.kind == core::DriveKind::kMecanum) {
    travel.base_mm = 0.5 * (wheels.track_width_mm + wheels.wheelbase_mm);
    const double r = wheels.mecanum_wheel_radius_mm;
    travel.left_mm = wheels.TicksToMm(r, TickDelta(last_.left_ticks, counts.left_ticks));
    travel.right_mm = wheels.TicksToMm(r, TickDelta(last_.right_ticks, counts.right_ticks));
    travel.rear_left_mm = wheels.TicksToMm(r, TickDelta(last_.rear_left_ticks, counts.rear_left_ticks));
    travel.rear_right_mm = wheels.TicksToMm(r, TickDelta(last_.rear_right_ticks, counts.rear_right_ticks));
    const Eigen::Vector4d wheel(travel.left_mm, travel.right_mm, travel.rear_left_mm, travel.rear_right_mm);
    fastest_mm = wheel.cwiseAbs().maxCoeff();
    variance = k * wheel.cwiseAbs();
  } else {
    travel.base_mm = wheels.track_width_mm;
    travel.left_mm = LeftTicksToMm(TickDelta(last_.left_ticks, counts.left_ticks));
    travel.right_mm = RightTicksToMm(TickDelta(last_.right_ticks, counts.right_ticks));
    fastest_mm = std::max(std::abs(travel.left_mm), std::abs(travel.right_mm));
    variance.head<2>() = Eigen::Vector2d(k * std::abs(travel.left_mm), k * std::abs(travel.right_mm));
  }
  last_time_ = time;
  last_ = counts;

  const double dt_s = core::ToSeconds(increment.dt);
  if (fastest_mm > options_.max_wheel_speed_mps * 1000.0 * dt_s) return core::Fail(OdometryFailure::kImplausibleJump);

  const Eigen::Vector3d motion = travel.Motion(Eigen::Vector2d::Zero());
  const double dx = motion.x(), dy = motion.y(), dtheta = motion.z();
  increment.previous_from_current = core::Pose2::Exp(motion);
  increment.forward_speed_mps = dx / dt_s * 1e-3;
  increment.lateral_speed_mps = dy / dt_s * 1e-3;
  increment.yaw_rate_radps = dtheta / dt_s;

  // Covariance propagation with the midpoint model (Siegwart et al., eqs. 5.6-5.9, with a
  // sideways component): phi = theta + dtheta/2,
  //   x' = x + dx cos(phi) - dy sin(phi), y' = y + dx sin(phi) + dy cos(phi), theta' = theta + dtheta,
  //   P' = Fp P Fp^T + Fw diag(variances) Fw^T, Fw = d(x', y', theta')/d(dx, dy, dtheta) d(dx, dy, dtheta)/d(inputs).
  const double phi = world_from_vehicle_.yaw_rad() + 0.5 * dtheta;
  const double c = std::cos(phi);
  const double s = std::sin(phi);
  const double dx_dphi = -dx * s - dy * c, dy_dphi = dx * c - dy * s;
  Eigen::Matrix3d f_pose = Eigen::Matrix3d::Identity();
  f_pose(0, 2) = dx_dphi;
  f_pose(1, 2) = dy_dphi;
  Eigen::Matrix3d f_motion;  // d(x', y', theta')/d(dx, dy, dtheta)
  f_motion << c, -s, 0.5 * dx_dphi, s, c, 0.5 * dy_dphi, 0.0, 0.0, 1.0;
  const Eigen::Matrix<double, 3, 4> f_wheels = f_motion * travel.InputJacobian();
  const Eigen::Matrix3d wheel_part = f_wheels * variance.asDiagonal() * f_wheels.transpose();
  covariance_ = f_pose * covariance_ * f_pose.transpose() + wheel_part;
  // The same in the previous vehicle frame: rotate the world-frame part back by its yaw.
  Eigen::Matrix3d to_vehicle = Eigen::Matrix3d::Identity();
  to_vehicle.topLeftCorner<2, 2>() = world_from_vehicle_.Rotation().transpose();
  increment.covariance = to_vehicle * wheel_part * to_vehicle.transpose();
  world_from_vehicle_ = world_from_vehicle_ * increment.previous_from_current;
  return increment;
}

}  // namespace mosaicloc::estimation
