#include "mosaicloc/core/pose2.hpp"

#include <cmath>
#include <numbers>

#include <Eigen/Geometry>

namespace mosaicloc::core {

double WrapAngle(double angle_rad) {
  constexpr double kTwoPi = 2.0 * std::numbers::pi;
  double wrapped = std::remainder(angle_rad, kTwoPi);  // in [-pi, pi]
  if (wrapped <= -std::numbers::pi) wrapped += kTwoPi;
  return wrapped;
}

Pose2::Pose2(double x_mm, double y_mm, double yaw_rad)
    : translation_mm_(x_mm, y_mm), yaw_rad_(WrapAngle(yaw_rad)) {}

Pose2::Pose2(const Eigen::Vector2d& translation_mm, double yaw_rad)
    : translation_mm_(translation_mm), yaw_rad_(WrapAngle(yaw_rad)) {}

Pose2 Pose2::FromMatrix(const Eigen::Matrix3d& matrix) {
  return Pose2(matrix(0, 2), matrix(1, 2), std::atan2(matrix(1, 0), matrix(0, 0)));
}

Eigen::Matrix2d Pose2::Rotation() const { return Eigen::Rotation2Dd(yaw_rad_).toRotationMatrix(); }

Eigen::Matrix3d Pose2::ToMatrix() const {
  Eigen::Matrix3d matrix = Eigen::Matrix3d::Identity();
  matrix.topLeftCorner<2, 2>() = Rotation();
  matrix.topRightCorner<2, 1>() = translation_mm_;
  return matrix;
}

Pose2 Pose2::operator*(const Pose2& b_from_c) const {
  return Pose2(translation_mm_ + Rotation() * b_from_c.translation_mm_, yaw_rad_ + b_from_c.yaw_rad_);
}

Eigen::Vector2d Pose2::operator*(const Eigen::Vector2d& point_b) const {
  return translation_mm_ + Rotation() * point_b;
}

Pose2 Pose2::Inverse() const {
  return Pose2(-(Rotation().transpose() * translation_mm_), -yaw_rad_);
}

// se2 exponential (Sola, Deray, Atchuthan, "A micro Lie theory for state estimation in
// robotics", 2018, the SE(2) appendix): with tangent (rho, theta),
//   t = V(theta) rho,  V = [[sin(th)/th, -(1-cos(th))/th], [(1-cos(th))/th, sin(th)/th]].
// Near theta = 0 the Taylor series keeps full precision.
namespace {
void SeriesV(double theta, double* a, double* b) {
  // a = sin(theta)/theta, b = (1 - cos(theta))/theta
  if (std::abs(theta) < 1e-6) {
    const double theta2 = theta * theta;
    *a = 1.0 - theta2 / 6.0;
    *b = theta / 2.0 - theta * theta2 / 24.0;
  } else {
    *a = std::sin(theta) / theta;
    *b = (1.0 - std::cos(theta)) / theta;
  }
}
}  // namespace

Pose2 Pose2::Exp(const Eigen::Vector3d& tangent) {
  double a = 0.0;
  double b = 0.0;
  SeriesV(tangent.z(), &a, &b);
  const Eigen::Vector2d t(a * tangent.x() - b * tangent.y(), b * tangent.x() + a * tangent.y());
  return Pose2(t, tangent.z());
}

Eigen::Vector3d Pose2::Log() const {
  double a = 0.0;
  double b = 0.0;
  SeriesV(yaw_rad_, &a, &b);
  // V^-1 = 1/(a^2 + b^2) [[a, b], [-b, a]]
  const double det = a * a + b * b;
  const Eigen::Vector2d rho((a * translation_mm_.x() + b * translation_mm_.y()) / det,
                            (-b * translation_mm_.x() + a * translation_mm_.y()) / det);
  return {rho.x(), rho.y(), yaw_rad_};
}

Pose2 Between(const Pose2& a_from_b, const Pose2& a_from_c) { return a_from_b.Inverse() * a_from_c; }

Pose2 Interpolate(const Pose2& start, const Pose2& end, double t) {
  return start * Pose2::Exp(t * Between(start, end).Log());
}

double YawDifference(const Pose2& a, const Pose2& b) { return WrapAngle(a.yaw_rad() - b.yaw_rad()); }

double Distance(const Pose2& a, const Pose2& b) {
  return (a.translation_mm() - b.translation_mm()).norm();
}

}  // namespace mosaicloc::core
