#pragma once

#include <Eigen/Core>

namespace mosaicloc::core {

/// Wraps an angle to (-pi, pi].
double WrapAngle(double angle_rad);

/// A rigid transform of the plane (SE2): rotation by yaw_rad, then translation (x_mm, y_mm).
/// `a_from_b` maps coordinates in frame b to frame a; names say both frames
/// (`world_from_vehicle`). Yaw is always kept wrapped to (-pi, pi].
class Pose2 {
 public:
  Pose2() = default;
  Pose2(double x_mm, double y_mm, double yaw_rad);
  Pose2(const Eigen::Vector2d& translation_mm, double yaw_rad);

  static Pose2 Identity() { return Pose2(); }
  /// From a 3x3 homogeneous matrix whose top-left block is a rotation (not checked beyond
  /// taking atan2 of its first column).
  static Pose2 FromMatrix(const Eigen::Matrix3d& matrix);

  double x_mm() const { return translation_mm_.x(); }
  double y_mm() const { return translation_mm_.y(); }
  double yaw_rad() const { return yaw_rad_; }
  const Eigen::Vector2d& translation_mm() const { return translation_mm_; }
  Eigen::Matrix2d Rotation() const;
  Eigen::Matrix3d ToMatrix() const;

  /// a_from_c = a_from_b * b_from_c.
  Pose2 operator*(const Pose2& b_from_c) const;
  /// Point p_b in frame b mapped to frame a.
  Eigen::Vector2d operator*(const Eigen::Vector2d& point_b) const;
  Pose2 Inverse() const;

  /// Exponential map of se2: tangent (v_x mm, v_y mm, omega rad) to the pose reached by
  /// moving with that constant body twist for unit time (an arc, or a line if omega = 0).
  static Pose2 Exp(const Eigen::Vector3d& tangent);
  /// Inverse of Exp: the constant body twist that reaches this pose in unit time.
  Eigen::Vector3d Log() const;

 private:
  Eigen::Vector2d translation_mm_ = Eigen::Vector2d::Zero();
  double yaw_rad_ = 0.0;
};

/// b_from_c given a_from_b and a_from_c: a_from_b^-1 * a_from_c.
Pose2 Between(const Pose2& a_from_b, const Pose2& a_from_c);

/// Geodesic interpolation on SE2: start * Exp(t * Log(start^-1 * end)). t = 0 gives start,
/// t = 1 gives end; for a vehicle moving with constant speed and curvature this is exact.
Pose2 Interpolate(const Pose2& start, const Pose2& end, double t);

/// Heading difference wrapped to (-pi, pi], and Euclidean distance in mm.
double YawDifference(const Pose2& a, const Pose2& b);
double Distance(const Pose2& a, const Pose2& b);

}  // namespace mosaicloc::core
