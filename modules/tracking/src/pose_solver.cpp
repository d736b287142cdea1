#include "mosaicloc/tracking/pose_solver.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include <Eigen/Eigenvalues>
#include <ceres/ceres.h>

namespace mosaicloc::tracking {
namespace {

// Residual of one correspondence (p in the camera floor frame C, w in the world, mm):
//
//   r(x, y, yaw) = ( R(yaw) p + (x, y) - w ) / s,      R(yaw) = [cos -sin; sin cos],
//
// s = the correspondence's relative standard deviation (sigma_i / median sigma), so r stays
// in mm for a typical correspondence and the loss scale keeps its meaning. Jacobian:
//   dr/dx = (1, 0) / s,  dr/dy = (0, 1) / s,  dr/dyaw = R'(yaw) p / s,
//   R'(yaw) p = (-sin p_x - cos p_y,  cos p_x - sin p_y).
class PlanarCost final : public ceres::SizedCostFunction<2, 3> {
 public:
  PlanarCost(const Correspondence& c, double scale) : c_(c), scale_(scale) {}
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    PlanarResidual(parameters[0], c_, scale_, residuals,
                   jacobians != nullptr && jacobians[0] != nullptr ? jacobians[0] : nullptr);
    return true;
  }

 private:
  Correspondence c_;
  double scale_;
};

double Median(std::vector<double> values) {
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2), values.end());
  return values[values.size() / 2];
}

struct Solved {
  bool converged = false;
  int iterations = 0;
};

// The robust loss of the options, or null for none.
std::unique_ptr<ceres::LossFunction> LossOf(const PoseSolverOptions& options) {
  if (options.loss == RobustLoss::kHuber) return std::make_unique<ceres::HuberLoss>(options.loss_scale_mm);
  if (options.loss == RobustLoss::kCauchy) return std::make_unique<ceres::CauchyLoss>(options.loss_scale_mm);
  return nullptr;
}

// Solves in place: `pose` is both the start and the result, and stays the problem's block.
Solved Solve(const std::vector<Correspondence>& cs, const std::vector<bool>& use, const std::vector<double>& scale,
             double* pose, const PoseSolverOptions& options, bool yaw_free) {
  Solved s;
  ceres::Problem problem;
  for (std::size_t i = 0; i < cs.size(); ++i) {
    if (!use[i]) continue;
    problem.AddResidualBlock(new PlanarCost(cs[i], scale[i]), LossOf(options).release(), pose);
  }
  if (!yaw_free) problem.SetManifold(pose, new ceres::SubsetManifold(3, {2}));
  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
  solver_options.max_num_iterations = options.max_iterations;
  solver_options.function_tolerance = 1e-12;
  solver_options.parameter_tolerance = 1e-12;
  solver_options.gradient_tolerance = 1e-14;
  solver_options.num_threads = 1;
  // The default logs every iteration: formatting those lines cost more than the solve.
  solver_options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, &problem, &summary);
  s.converged = summary.termination_type == ceres::CONVERGENCE;
  s.iterations = static_cast<int>(summary.iterations.size());
  return s;
}

// The covariance of the pose at the solution, (J^T J)^-1 of the used residuals, as
// ceres::Covariance finds it: each residual's Jacobian carries the robust loss's correction,
// which for Huber and Cauchy (rho'' <= 0) is a factor sqrt(rho'(|r|^2)). Computed here because
// ceres::Covariance's set-up costs more than the whole solve of three parameters. False when
// J^T J is rank deficient (a direction the residuals do not determine).
bool PoseCovariance(const std::vector<Correspondence>& cs, const std::vector<bool>& use,
                    const std::vector<double>& scale, const double* pose, const PoseSolverOptions& options,
                    Eigen::Matrix3d* covariance) {
  const std::unique_ptr<ceres::LossFunction> loss = LossOf(options);
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < cs.size(); ++i) {
    if (!use[i]) continue;
    double r[2];
    Eigen::Matrix<double, 2, 3, Eigen::RowMajor> j;
    PlanarResidual(pose, cs[i], scale[i], r, j.data());
    double rho[3] = {0.0, 1.0, 0.0};
    if (loss) loss->Evaluate(r[0] * r[0] + r[1] * r[1], rho);
    information += rho[1] * j.transpose() * j;
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(information);
  const Eigen::Vector3d values = eigen.eigenvalues();  // ascending
  if (!(values(0) > 1e-14 * values(2))) return false;
  *covariance = eigen.eigenvectors() * values.cwiseInverse().asDiagonal() * eigen.eigenvectors().transpose();
  return true;
}

}  // namespace

void PlanarResidual(const double* pose, const Correspondence& c, double scale, double* residual,
                    double* jacobian) {
  const double cos_yaw = std::cos(pose[2]), sin_yaw = std::sin(pose[2]);
  const double px = c.camera_mm.x(), py = c.camera_mm.y();
  residual[0] = (cos_yaw * px - sin_yaw * py + pose[0] - c.world_mm.x()) / scale;
  residual[1] = (sin_yaw * px + cos_yaw * py + pose[1] - c.world_mm.y()) / scale;
  if (jacobian == nullptr) return;
  jacobian[0] = 1.0 / scale;
  jacobian[1] = 0.0;
  jacobian[2] = (-sin_yaw * px - cos_yaw * py) / scale;
  jacobian[3] = 0.0;
  jacobian[4] = 1.0 / scale;
  jacobian[5] = (cos_yaw * px - sin_yaw * py) / scale;
}

bool PoseSolverOptions::Check(std::string* why) const {
  auto fail = [why](const char* message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (!(loss_scale_mm > 0.0)) return fail("loss_scale_mm must be > 0");
  if (!(outlier_threshold_mm > 0.0)) return fail("outlier_threshold_mm must be > 0");
  if (min_inliers < 1) return fail("min_inliers must be >= 1");
  if (max_iterations < 1) return fail("max_iterations must be >= 1");
  return true;
}

const char* ToString(PoseFailure failure) {
  switch (failure) {
    case PoseFailure::kNone: return "ok";
    case PoseFailure::kTooFewInliers: return "too few inliers";
    case PoseFailure::kNotConverged: return "not converged";
  }
  return "unknown";
}

PoseSolution SolvePlanarPose(const std::vector<Correspondence>& correspondences, const core::Pose2& initial,
                             const PoseSolverOptions& options) {
  PoseSolution solution;
  solution.world_from_camera = initial;
  const std::size_t n = correspondences.size();
  solution.inlier.assign(n, false);
  solution.residual_mm.assign(n, 0.0);
  if (n == 0 || static_cast<int>(n) < options.min_inliers) {
    solution.failure = PoseFailure::kTooFewInliers;
    return solution;
  }
  std::vector<double> sigmas;
  sigmas.reserve(n);
  for (const Correspondence& c : correspondences) sigmas.push_back(std::max(c.sigma_mm, 1e-9));
  const double sigma_ref = Median(sigmas);
  std::vector<double> scale(n);
  for (std::size_t i = 0; i < n; ++i) scale[i] = sigmas[i] / sigma_ref;

  double pose[3] = {initial.x_mm(), initial.y_mm(), initial.yaw_rad()};
  std::vector<bool> use(n, true);
  Solved solved = Solve(correspondences, use, scale, pose, options, n >= 2);

  // Outliers by their residual at the robust solution, then a clean solve on the inliers.
  auto residual_of = [&](std::size_t i, const double* at) {
    double r[2];
    PlanarResidual(at, correspondences[i], 1.0, r, nullptr);
    return std::hypot(r[0], r[1]);
  };
  int inliers = 0;
  for (std::size_t i = 0; i < n; ++i) {
    use[i] = residual_of(i, pose) <= options.outlier_threshold_mm;
    inliers += use[i] ? 1 : 0;
  }
  if (inliers < options.min_inliers) {
    solution.failure = PoseFailure::kTooFewInliers;
    solution.inliers = inliers;
    solution.inlier = use;
    return solution;
  }
  if (inliers < static_cast<int>(n)) {
    solved = Solve(correspondences, use, scale, pose, options, inliers >= 2);
  }
  solution.iterations = solved.iterations;
  solution.world_from_camera = core::Pose2(pose[0], pose[1], pose[2]);
  solution.inlier = use;
  solution.inliers = inliers;
  double sum_sq = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    solution.residual_mm[i] = residual_of(i, pose);
    if (use[i]) sum_sq += solution.residual_mm[i] * solution.residual_mm[i];
  }
  solution.rms_residual_mm = std::sqrt(sum_sq / inliers);
  if (!solved.converged) {
    solution.failure = PoseFailure::kNotConverged;
    return solution;
  }

  if (!options.compute_covariance) {
    solution.covariance.setConstant(std::numeric_limits<double>::quiet_NaN());
    return solution;
  }
  // Residuals are in units of sigma_ref mm: scale the unit-weight covariance by sigma_ref^2.
  // Inliers all at one point leave the yaw free.
  const std::size_t first = static_cast<std::size_t>(std::find(use.begin(), use.end(), true) - use.begin());
  bool spread = false;
  for (std::size_t i = first + 1; i < n && !spread; ++i) {
    spread = use[i] && (correspondences[i].camera_mm - correspondences[first].camera_mm).squaredNorm() > 1e-12;
  }
  Eigen::Matrix3d unit;
  if (spread && PoseCovariance(correspondences, use, scale, pose, options, &unit)) {
    solution.covariance = unit * sigma_ref * sigma_ref;
  } else {
    // One correspondence, or several at one point: translation only, the yaw undetermined.
    solution.covariance = Eigen::Matrix3d::Zero();
    solution.covariance(0, 0) = solution.covariance(1, 1) = sigma_ref * sigma_ref;
    solution.covariance(2, 2) = std::numeric_limits<double>::infinity();
  }
  return solution;
}

}  // namespace mosaicloc::tracking
