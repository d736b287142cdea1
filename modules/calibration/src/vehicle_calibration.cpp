#include "mosaicloc/calibration/vehicle_calibration.hpp"

#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <opencv2/core.hpp>

namespace mosaicloc::calibration {
namespace {

using Parameters = Eigen::Matrix<double, 6, 1>;  // x_mm, y_mm, yaw_rad, r_l, r_r, b

core::Pose2 Arc(double left_wheel_rad, double right_wheel_rad, const Parameters& p) {
  const double d_l = p(3) * left_wheel_rad, d_r = p(4) * right_wheel_rad;
  const double d = 0.5 * (d_l + d_r), theta = (d_r - d_l) / p(5);
  // sin(theta)/theta and (1 - cos(theta))/theta, by series near zero.
  const double a = std::abs(theta) < 1e-6 ? 1.0 - theta * theta / 6.0 : std::sin(theta) / theta;
  const double b = std::abs(theta) < 1e-6 ? 0.5 * theta : (1.0 - std::cos(theta)) / theta;
  return {d * a, d * b, theta};
}

core::Pose2 VehicleMotion(const DriveStep& step, const Parameters& p) {
  if (step.arcs.empty()) return Arc(step.left_wheel_rad, step.right_wheel_rad, p);
  core::Pose2 motion;
  for (const WheelTurn& turn : step.arcs) motion = motion * Arc(turn.left_wheel_rad, turn.right_wheel_rad, p);
  return motion;
}

WheelTurn Total(const DriveStep& step) {
  if (step.arcs.empty()) return {step.left_wheel_rad, step.right_wheel_rad};
  WheelTurn total;
  for (const WheelTurn& turn : step.arcs) {
    total.left_wheel_rad += turn.left_wheel_rad;
    total.right_wheel_rad += turn.right_wheel_rad;
  }
  return total;
}

Eigen::VectorXd Residuals(const std::vector<DriveStep>& steps, const Parameters& p,
                          const VehicleCalibrationOptions& options) {
  const core::Pose2 vehicle_from_camera(p(0), p(1), p(2));
  const core::Pose2 camera_from_vehicle = vehicle_from_camera.Inverse();
  Eigen::VectorXd r(3 * static_cast<long>(steps.size()));
  for (std::size_t i = 0; i < steps.size(); ++i) {
    const core::Pose2 predicted = camera_from_vehicle * VehicleMotion(steps[i], p) * vehicle_from_camera;
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
  // Central differences with steps scaled to each parameter (mm, rad, mm).
  const double h[6] = {1e-4, 1e-4, 1e-7, 1e-5, 1e-5, 1e-4};
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
double InitialYaw(const std::vector<DriveStep>& steps, double fallback) {
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  for (const DriveStep& step : steps) {
    const WheelTurn total = Total(step);
    const double forward = total.left_wheel_rad + total.right_wheel_rad;
    if (forward > 0.0 && std::abs(total.right_wheel_rad - total.left_wheel_rad) < 0.02 * forward) {
      sum += step.previous_from_current_camera.translation_mm();
    }
  }
  return sum.norm() > 0.0 ? -std::atan2(sum.y(), sum.x()) : fallback;
}

}  // namespace

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
  Parameters p;
  p << options.initial_vehicle_from_camera.x_mm(), options.initial_vehicle_from_camera.y_mm(),
      InitialYaw(steps, options.initial_vehicle_from_camera.yaw_rad()), options.initial_wheels.left_wheel_radius_mm,
      options.initial_wheels.right_wheel_radius_mm, options.initial_wheels.track_width_mm;
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
      if (candidate(3) <= 0.0 || candidate(4) <= 0.0 || candidate(5) <= 0.0) {
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
    result.message = "the drive does not determine every parameter: it needs a straight run and a turn in place";
  } else {
    const long dof = std::max<long>(1, r.size() - 6);
    double variance = cost / static_cast<double>(dof);
    if (options.independent_steps > 0 && options.independent_steps < result.steps) {
      variance *= static_cast<double>(result.steps) / static_cast<double>(options.independent_steps);
    }
    result.sigma = (lu.inverse().diagonal() * variance).cwiseSqrt();
  }
  result.vehicle_from_camera = core::Pose2(p(0), p(1), std::remainder(p(2), 2.0 * M_PI));
  result.wheels = core::WheelGeometry{};
  result.wheels.left_wheel_radius_mm = p(3);
  result.wheels.right_wheel_radius_mm = p(4);
  result.wheels.track_width_mm = p(5);
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
