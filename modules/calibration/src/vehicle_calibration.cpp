#include "mosaicloc/calibration/vehicle_calibration.hpp"

#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <opencv2/core.hpp>

namespace mosaicloc::calibration {
namespace {

// x_mm, y_mm, yaw_rad of vehicle_from_camera, then the kind's: r_l, r_r, b (differential) or
// r, l, steering offset in rad (tricycle).
using Parameters = Eigen::Matrix<double, 6, 1>;

core::Pose2 Arc(const WheelTurn& turn, core::DriveKind kind, const Parameters& p) {
  const Eigen::Vector2d moved = ArcLengthAndTurn(turn, kind, p.tail<3>());
  const double d = moved.x(), theta = moved.y();
  // sin(theta)/theta and (1 - cos(theta))/theta, by series near zero.
  const double a = std::abs(theta) < 1e-6 ? 1.0 - theta * theta / 6.0 : std::sin(theta) / theta;
  const double b = std::abs(theta) < 1e-6 ? 0.5 * theta : (1.0 - std::cos(theta)) / theta;
  return {d * a, d * b, theta};
}

core::Pose2 VehicleMotion(const DriveStep& step, core::DriveKind kind, const Parameters& p) {
  core::Pose2 motion;
  for (const WheelTurn& turn : step.arcs) motion = motion * Arc(turn, kind, p);
  return motion;
}

// Whether a step drove straight ahead under the initial geometry: both wheels alike, or the
// steered wheel within 1 degree of straight.
bool Straight(const DriveStep& step, core::DriveKind kind, const Parameters& p) {
  double forward = 0.0, turned = 0.0;
  for (const WheelTurn& turn : step.arcs) {
    if (kind == core::DriveKind::kTricycle) {
      if (std::abs(turn.steering_rad + p(5)) > M_PI / 180.0) return false;
      forward += turn.drive_wheel_rad;
    } else {
      forward += turn.left_wheel_rad + turn.right_wheel_rad;
      turned += turn.right_wheel_rad - turn.left_wheel_rad;
    }
  }
  return forward > 0.0 && std::abs(turned) < 0.02 * forward;
}

Eigen::VectorXd Residuals(const std::vector<DriveStep>& steps, const Parameters& p,
                          const VehicleCalibrationOptions& options) {
  const core::Pose2 vehicle_from_camera(p(0), p(1), p(2));
  const core::Pose2 camera_from_vehicle = vehicle_from_camera.Inverse();
  Eigen::VectorXd r(3 * static_cast<long>(steps.size()));
  for (std::size_t i = 0; i < steps.size(); ++i) {
    const core::Pose2 predicted =
        camera_from_vehicle * VehicleMotion(steps[i], options.initial_wheels.kind, p) * vehicle_from_camera;
    const core::Pose2 error = predicted.Inverse() * steps[i].previous_from_current_camera;
    const long k = 3 * static_cast<long>(i);
    r(k) = error.x_mm() / options.registration_sigma_mm;
    r(k + 1) = error.y_mm() / options.registration_sigma_mm;
    r(k + 2) = std::remainder(error.yaw_rad(), 2.0 * M_PI) / options.registration_sigma_rad;
  }
  return r;
}

Eigen::MatrixXd Jacobian(const std::vector<DriveStep>& steps, const Parameters& p,
                         const VehicleCalibrationOptions& options) {
  // Central differences with steps scaled to each parameter (mm, rad, mm; a tricycle's
  // steering offset in rad).
  const bool tricycle = options.initial_wheels.kind == core::DriveKind::kTricycle;
  const double h[6] = {1e-4, 1e-4, 1e-7, 1e-5, tricycle ? 1e-4 : 1e-5, tricycle ? 1e-7 : 1e-4};
  Eigen::MatrixXd j(3 * static_cast<long>(steps.size()), 6);
  for (int c = 0; c < 6; ++c) {
    Parameters plus = p, minus = p;
    plus(c) += h[c];
    minus(c) -= h[c];
    j.col(c) = (Residuals(steps, plus, options) - Residuals(steps, minus, options)) / (2.0 * h[c]);
  }
  return j;
}

// The mounting yaw seen by the straight steps: the vehicle moves along its x axis, so the
// camera translates along R(-yaw) (1, 0).
double InitialYaw(const std::vector<DriveStep>& steps, core::DriveKind kind, const Parameters& p, double fallback) {
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  for (const DriveStep& step : steps) {
    if (Straight(step, kind, p)) sum += step.previous_from_current_camera.translation_mm();
  }
  return sum.norm() > 0.0 ? -std::atan2(sum.y(), sum.x()) : fallback;
}

// Whether the kind's wheel parameters can be what a vehicle has (lengths > 0).
bool Possible(const Parameters& p, core::DriveKind kind) {
  return p(3) > 0.0 && p(4) > 0.0 && (kind == core::DriveKind::kTricycle || p(5) > 0.0);
}

}  // namespace

Eigen::Vector2d ArcLengthAndTurn(const WheelTurn& turn, core::DriveKind kind, const Eigen::Vector3d& wheels) {
  if (kind == core::DriveKind::kTricycle) {
    const double d_w = wheels(0) * turn.drive_wheel_rad, psi = turn.steering_rad + wheels(2);
    return {d_w * std::cos(psi), d_w * std::sin(psi) / wheels(1)};
  }
  const double d_l = wheels(0) * turn.left_wheel_rad, d_r = wheels(1) * turn.right_wheel_rad;
  return {0.5 * (d_l + d_r), (d_r - d_l) / wheels(2)};
}

bool VehicleCalibrationOptions::Check(std::string* why) const {
  if (!initial_wheels.Check(why)) {
    *why = "vehicle calibration's initial wheels: " + *why;
    return false;
  }
  if (!(registration_sigma_mm > 0.0 && registration_sigma_rad > 0.0)) {
    *why = "vehicle calibration registration sigmas must be positive";
    return false;
  }
  if (independent_steps < 0) {
    *why = "vehicle calibration independent_steps must be >= 0";
    return false;
  }
  if (max_iterations < 1) {
    *why = "vehicle calibration max_iterations must be >= 1";
    return false;
  }
  return true;
}

VehicleCalibrationResult CalibrateVehicle(const std::vector<DriveStep>& steps,
                                          const VehicleCalibrationOptions& options) {
  VehicleCalibrationResult result;
  result.steps = static_cast<int>(steps.size());
  std::string why;
  if (!options.Check(&why)) {
    result.message = why;
    return result;
  }
  if (steps.size() < 4) {
    result.message = "a calibration drive needs at least 4 registered steps";
    return result;
  }
  const core::WheelGeometry& initial = options.initial_wheels;
  const core::DriveKind kind = initial.kind;
  Parameters p;
  if (kind == core::DriveKind::kTricycle) {
    p << 0.0, 0.0, 0.0, initial.drive_wheel_radius_mm, initial.wheelbase_mm, initial.steering_offset_deg * M_PI / 180.0;
  } else {
    p << 0.0, 0.0, 0.0, initial.left_wheel_radius_mm, initial.right_wheel_radius_mm, initial.track_width_mm;
  }
  p(0) = options.initial_vehicle_from_camera.x_mm();
  p(1) = options.initial_vehicle_from_camera.y_mm();
  p(2) = InitialYaw(steps, kind, p, options.initial_vehicle_from_camera.yaw_rad());
  Eigen::VectorXd r = Residuals(steps, p, options);
  double cost = r.squaredNorm();
  double lambda = 1e-4;
  Eigen::MatrixXd j;
  for (result.iterations = 0; result.iterations < options.max_iterations; ++result.iterations) {
    j = Jacobian(steps, p, options);
    const Eigen::Matrix<double, 6, 6> jtj = j.transpose() * j;
    const Parameters g = j.transpose() * r;
    bool improved = false;
    for (int attempt = 0; attempt < 20 && !improved; ++attempt) {
      Eigen::Matrix<double, 6, 6> damped = jtj;
      damped.diagonal() += lambda * jtj.diagonal().cwiseMax(1e-12);
      const Parameters delta = -damped.ldlt().solve(g);
      const Parameters candidate = p + delta;
      if (!Possible(candidate, kind)) {
        lambda *= 10.0;
        continue;
      }
      const Eigen::VectorXd r_candidate = Residuals(steps, candidate, options);
      const double candidate_cost = r_candidate.squaredNorm();
      if (candidate_cost < cost) {
        const double relative = (cost - candidate_cost) / std::max(cost, 1e-300);
        p = candidate;
        r = r_candidate;
        cost = candidate_cost;
        lambda = std::max(lambda / 10.0, 1e-12);
        improved = true;
        if (relative < 1e-12 || delta.norm() < 1e-10) result.converged = true;
      } else {
        lambda *= 10.0;
      }
    }
    if (!improved) result.converged = true;  // no step lowers the cost: at the minimum
    if (result.converged) break;
  }
  if (!result.converged) result.message = "did not converge in " + std::to_string(options.max_iterations) + " iterations";

  j = Jacobian(steps, p, options);
  const Eigen::Matrix<double, 6, 6> jtj = j.transpose() * j;
  // Identifiability: the Jacobian with unit-norm columns must have full rank, with a margin.
  Eigen::MatrixXd normalized = j;
  bool determined = true;
  for (int c = 0; c < 6; ++c) {
    const double norm = j.col(c).norm();
    determined = determined && norm > 1e-9;
    if (norm > 0.0) normalized.col(c) /= norm;
  }
  // OpenCV's compiled SVD: Eigen's JacobiSVD template costs about a minute of compilation per
  // translation unit under the sanitizers.
  cv::Mat normalized_cv(static_cast<int>(normalized.rows()), 6, CV_64F);
  for (long row = 0; row < normalized.rows(); ++row) {
    for (int c = 0; c < 6; ++c) normalized_cv.at<double>(static_cast<int>(row), c) = normalized(row, c);
  }
  cv::Mat singular_values;
  cv::SVD::compute(normalized_cv, singular_values, cv::SVD::NO_UV);  // descending order
  determined = determined && singular_values.at<double>(5) > 1e-6 * singular_values.at<double>(0);
  const Eigen::FullPivLU<Eigen::Matrix<double, 6, 6>> lu(jtj);
  if (!determined || lu.rank() < 6) {
    result.converged = false;
    result.message = kind == core::DriveKind::kTricycle
                         ? "the drive does not determine every parameter: it needs a straight run and a turn in "
                           "place (the steered wheel across, pivoting about the fixed axle)"
                         : "the drive does not determine every parameter: it needs a straight run and a turn in place";
  } else {
    const long dof = std::max<long>(1, r.size() - 6);
    double variance = cost / static_cast<double>(dof);
    if (options.independent_steps > 0 && options.independent_steps < result.steps) {
      variance *= static_cast<double>(result.steps) / static_cast<double>(options.independent_steps);
    }
    result.sigma = (lu.inverse().diagonal() * variance).cwiseSqrt();
  }
  result.vehicle_from_camera = core::Pose2(p(0), p(1), std::remainder(p(2), 2.0 * M_PI));
  result.wheels = initial;
  if (kind == core::DriveKind::kTricycle) {
    result.wheels.drive_wheel_radius_mm = p(3);
    result.wheels.wheelbase_mm = p(4);
    result.wheels.steering_offset_deg = p(5) * 180.0 / M_PI;
  } else {
    result.wheels.left_wheel_radius_mm = p(3);
    result.wheels.right_wheel_radius_mm = p(4);
    result.wheels.track_width_mm = p(5);
  }
  double sum_t = 0.0, sum_r = 0.0;
  for (long i = 0; i < r.size() / 3; ++i) {
    sum_t += (r(3 * i) * r(3 * i) + r(3 * i + 1) * r(3 * i + 1)) * options.registration_sigma_mm * options.registration_sigma_mm;
    sum_r += r(3 * i + 2) * r(3 * i + 2) * options.registration_sigma_rad * options.registration_sigma_rad;
  }
  result.rms_translation_mm = std::sqrt(sum_t / static_cast<double>(steps.size()));
  result.rms_rotation_rad = std::sqrt(sum_r / static_cast<double>(steps.size()));
  return result;
}

}  // namespace mosaicloc::calibration
