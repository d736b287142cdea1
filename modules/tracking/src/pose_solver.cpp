#include "mosaicloc/tracking/pose_solver.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include <Eigen/Eigenvalues>
#include <ceres/ceres.h>
#include <ceres/tiny_solver.h>

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

double Median(std::vector<double> values) {
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2), values.end());
  return values[values.size() / 2];
}

// The robust loss of the options, or null for none.
std::unique_ptr<ceres::LossFunction> LossOf(const PoseSolverOptions& options) {
  if (options.loss == RobustLoss::kHuber) return std::make_unique<ceres::HuberLoss>(options.loss_scale_mm);
  if (options.loss == RobustLoss::kCauchy) return std::make_unique<ceres::CauchyLoss>(options.loss_scale_mm);
  return nullptr;
}

// rho'(|r|^2) of the loss at residual r (1 without a loss): the weight of the residual in a
// reweighting round, and the square of the factor the loss puts on its Jacobian.
double LossWeight(const ceres::LossFunction* loss, const double* r) {
  double rho[3] = {0.0, 1.0, 0.0};
  if (loss != nullptr) loss->Evaluate(r[0] * r[0] + r[1] * r[1], rho);
  return rho[1];
}

// The used correspondences' residuals, each weighted by sqrt(w_i), as a ceres::TinySolver
// function of (x, y, yaw), or of (x, y) with the yaw held (P = 2).
template <int P>
struct WeightedResiduals {
  using Scalar = double;
  enum { NUM_RESIDUALS = Eigen::Dynamic, NUM_PARAMETERS = P };
  const std::vector<const Correspondence*>& cs;
  const std::vector<double>& scale;
  const std::vector<double>& root_weight;
  double yaw;
  int NumResiduals() const { return static_cast<int>(2 * cs.size()); }
  // (x, y, yaw) of the parameters x.
  void PoseOf(const double* x, double* pose) const {
    pose[0] = x[0];
    pose[1] = x[1];
    pose[2] = P == 3 ? x[P - 1] : yaw;
  }
  bool operator()(const double* x, double* residuals, double* jacobian) const {
    double pose[3];
    PoseOf(x, pose);
    const std::size_t n = 2 * cs.size();
    for (std::size_t i = 0; i < cs.size(); ++i) {
      double r[2], j[6];
      PlanarResidual(pose, *cs[i], scale[i], r, jacobian != nullptr ? j : nullptr);
      residuals[2 * i] = root_weight[i] * r[0];
      residuals[2 * i + 1] = root_weight[i] * r[1];
      if (jacobian == nullptr) continue;
      for (int p = 0; p < P; ++p) {  // column-major, n x P
        jacobian[static_cast<std::size_t>(p) * n + 2 * i] = root_weight[i] * j[p];
        jacobian[static_cast<std::size_t>(p) * n + 2 * i + 1] = root_weight[i] * j[3 + p];
      }
    }
    return true;
  }
};

struct Solved {
  bool converged = false;
  int iterations = 0;
};

// Minimises sum_i rho(|r_i|^2) over the used correspondences, in place (`pose` is the start
// and the result), by iteratively reweighted least squares: each round weighs residual i by
// rho'(|r_i|^2) at the current pose (1 without a loss) and solves that weighted problem with
// ceres::TinySolver (Levenberg-Marquardt). A fixed point is a stationary point of the robust
// cost, sum_i rho'_i J_i^T r_i = 0, the same optimum ceres::Solve finds; for three parameters
// and a handful of residuals ceres::Solve's set-up cost about ten times the arithmetic.
template <int P>
Solved SolveRounds(const std::vector<const Correspondence*>& cs, const std::vector<double>& scale, double* pose,
                   const PoseSolverOptions& options) {
  const std::unique_ptr<ceres::LossFunction> loss = LossOf(options);
  std::vector<double> root_weight(cs.size(), 1.0);
  const WeightedResiduals<P> residuals{cs, scale, root_weight, pose[2]};
  ceres::TinySolver<WeightedResiduals<P>> solver;
  solver.options.max_num_iterations = options.max_iterations;
  solver.options.gradient_tolerance = 1e-14;
  solver.options.parameter_tolerance = 1e-12;
  solver.options.function_tolerance = 1e-12;
  Solved s;
  Eigen::Matrix<double, P, 1> x;
  for (int p = 0; p < P; ++p) x(p) = pose[p];
  for (int round = 0; round < options.max_iterations; ++round) {
    s.iterations = round + 1;
    double at[3];
    residuals.PoseOf(x.data(), at);
    for (std::size_t i = 0; i < cs.size(); ++i) {
      double r[2];
      PlanarResidual(at, *cs[i], scale[i], r, nullptr);
      root_weight[i] = std::sqrt(LossWeight(loss.get(), r));
    }
    const Eigen::Matrix<double, P, 1> before = x;
    const auto& summary = solver.Solve(residuals, &x);
    if (summary.status == ceres::TinySolver<WeightedResiduals<P>>::HIT_MAX_ITERATIONS || !x.allFinite()) break;
    // Without a loss the weights never change: one round is the solution.
    if (!loss || (x - before).norm() <= 1e-12 * (before.norm() + 1e-12)) {
      s.converged = true;
      break;
    }
  }
  for (int p = 0; p < P; ++p) pose[p] = x(p);
  return s;
}

// Solves in place: `pose` is both the start and the result. With !yaw_free the yaw is held.
Solved Solve(const std::vector<Correspondence>& cs, const std::vector<bool>& use, const std::vector<double>& scale,
             double* pose, const PoseSolverOptions& options, bool yaw_free) {
  std::vector<const Correspondence*> used;
  std::vector<double> used_scale;
  for (std::size_t i = 0; i < cs.size(); ++i) {
    if (!use[i]) continue;
    used.push_back(&cs[i]);
    used_scale.push_back(scale[i]);
  }
  return yaw_free ? SolveRounds<3>(used, used_scale, pose, options) : SolveRounds<2>(used, used_scale, pose, options);
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
    information += LossWeight(loss.get(), r) * j.transpose() * j;
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

const char* ToString(RobustLoss loss) {
  switch (loss) {
    case RobustLoss::kNone: return "none";
    case RobustLoss::kHuber: return "huber";
    case RobustLoss::kCauchy: return "cauchy";
  }
  return "unknown";
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
