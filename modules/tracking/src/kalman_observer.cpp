// The founding paper's pose observer (Kelly, section 3): the pose refined by a Kalman
// measurement update over the template correspondences, iterated about the latest estimate.
//
// State x = (x, y, yaw) or (x, y, yaw, k) with the image scale k. Prior x0 = the initial pose
// (k = 1) with covariance P0 = diag(observer_prior_sigma_*)^2. Measurement of correspondence i:
//
//   z_i = w_i = h_i(x) + n_i,   h_i(x) = k R(yaw) p_i + (x, y),   n_i ~ N(0, sigma_i^2 I),
//
// p_i the template centre in the camera floor frame, w_i where it matched on the map. The
// iterated extended Kalman filter's update (Bell and Cathey, "The iterated Kalman filter update
// as a Gauss-Newton method", IEEE TAC 1993): with H_j the Jacobian of h at x_j,
//
//   K_j = P0 H_j^T (H_j P0 H_j^T + R)^-1,   x_{j+1} = x0 + K_j (z - h(x_j) - H_j (x0 - x_j)),
//
// until the step is negligible; the posterior covariance is (I - K H) P0 at the last x.

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "mosaicloc/tracking/pose_solver.hpp"
#include "pose_solver_internal.hpp"

namespace mosaicloc::tracking {
namespace {

struct ObserverUpdate {
  Eigen::Vector4d x = Eigen::Vector4d::Zero();  ///< (x, y, yaw, k); what is not estimated keeps x0's
  Eigen::MatrixXd covariance;                   ///< P x P
  int iterations = 0;
  bool converged = false;
};

// The iterated update of the first `p` states (2: x, y; 3: and yaw; 4: and k) from the used
// correspondences.
ObserverUpdate IteratedUpdate(const std::vector<Correspondence>& cs, const std::vector<bool>& use,
                              const Eigen::Vector4d& x0, const Eigen::Vector4d& prior_sigma, int p, int max_iterations) {
  const int m = static_cast<int>(std::count(use.begin(), use.end(), true));
  const Eigen::MatrixXd prior = prior_sigma.head(p).cwiseAbs2().asDiagonal();
  Eigen::MatrixXd h(2 * m, p);
  Eigen::VectorXd innovation(2 * m);
  Eigen::VectorXd noise(2 * m);
  Eigen::MatrixXd gain;
  ObserverUpdate update;
  update.x = x0;
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    int row = 0;
    for (std::size_t i = 0; i < cs.size(); ++i) {
      if (!use[i]) continue;
      double r[2];
      double j[8];  // 2 x 4, row-major: d(h - w) / d(x, y, yaw, k)
      SimilarityResidual(update.x.data(), cs[i], 1.0, r, j);
      for (int k = 0; k < 2; ++k) {
        for (int c = 0; c < p; ++c) h(row + k, c) = j[4 * k + c];
        innovation(row + k) = -r[k];  // z - h(x_j)
        noise(row + k) = cs[i].sigma_mm * cs[i].sigma_mm;
      }
      row += 2;
    }
    // z - h(x_j) - H (x0 - x_j)
    const Eigen::VectorXd v = innovation - h * (x0 - update.x).head(p);
    Eigen::MatrixXd s = h * prior * h.transpose();
    s.diagonal() += noise;
    gain = s.ldlt().solve(h * prior).transpose();  // P0 H^T S^-1 (S and P0 symmetric)
    Eigen::Vector4d next = x0;
    next.head(p) += gain * v;
    const Eigen::Vector4d step = next - update.x;
    update.x = next;
    update.iterations = iteration + 1;
    if (!next.allFinite()) return update;
    if (step.head<2>().norm() < 1e-7 && std::abs(step(2)) < 1e-10 && std::abs(step(3)) < 1e-10) {
      update.converged = true;
      break;
    }
  }
  Eigen::MatrixXd posterior = (Eigen::MatrixXd::Identity(p, p) - gain * h) * prior;
  update.covariance = 0.5 * (posterior + posterior.transpose());
  return update;
}

}  // namespace

PoseSolution ObservePlanarPose(const std::vector<Correspondence>& correspondences, const core::Pose2& initial,
                               const PoseSolverOptions& options) {
  PoseSolution solution = internal::StartSolution(correspondences, initial, options.min_inliers);
  if (!solution.ok()) return solution;
  const std::size_t n = correspondences.size();
  const Eigen::Vector4d x0(initial.x_mm(), initial.y_mm(), initial.yaw_rad(), 1.0);
  const Eigen::Vector4d prior_sigma(options.observer_prior_sigma_mm, options.observer_prior_sigma_mm,
                                    options.observer_prior_sigma_deg * std::numbers::pi / 180.0,
                                    options.observer_prior_sigma_scale);
  std::vector<bool> use(n, true);
  int inliers = static_cast<int>(n);
  auto residual_of = [&](std::size_t i, const Eigen::Vector4d& x) {
    double r[2];
    SimilarityResidual(x.data(), correspondences[i], 1.0, r, nullptr);
    return std::hypot(r[0], r[1]);
  };
  ObserverUpdate update;
  int p = 3;
  while (true) {
    const int distinct = internal::DistinctPoints(correspondences, use, 4);
    p = options.estimate_scale && distinct >= 4 ? 4 : distinct >= 2 ? 3 : 2;
    update = IteratedUpdate(correspondences, use, x0, prior_sigma, p, options.max_iterations);
    // Data snooping: the worst correspondence beyond the threshold goes, and the update is run
    // again without it (one gross outlier drags the others' residuals with it).
    std::size_t worst = n;
    double worst_mm = options.outlier_threshold_mm;
    for (std::size_t i = 0; i < n; ++i) {
      if (!use[i]) continue;
      const double r = residual_of(i, update.x);
      if (!(r <= worst_mm)) {
        worst = i;
        worst_mm = std::isfinite(r) ? r : std::numeric_limits<double>::max();
      }
    }
    if (worst == n) break;
    use[worst] = false;
    if (--inliers < options.min_inliers) {
      solution.failure = PoseFailure::kTooFewInliers;
      solution.inliers = inliers;
      solution.inlier = use;
      return solution;
    }
  }
  solution.iterations = update.iterations;
  solution.world_from_camera = core::Pose2(update.x(0), update.x(1), update.x(2));
  solution.scale = update.x(3);
  solution.scale_estimated = p == 4;
  solution.inlier = use;
  solution.inliers = inliers;
  double sum_sq = 0.0, chi2 = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    solution.residual_mm[i] = residual_of(i, update.x);
    if (!use[i]) continue;
    sum_sq += solution.residual_mm[i] * solution.residual_mm[i];
    chi2 += std::pow(solution.residual_mm[i] / std::max(correspondences[i].sigma_mm, 1e-9), 2);
  }
  solution.rms_residual_mm = std::sqrt(sum_sq / inliers);
  if (!update.converged) {
    solution.failure = PoseFailure::kNotConverged;
    return solution;
  }
  if (!options.compute_covariance) {
    solution.covariance.setConstant(std::numeric_limits<double>::quiet_NaN());
    return solution;
  }
  const int redundancy = 2 * inliers - p;
  if (options.posterior_variance && redundancy > 0) solution.variance_factor = std::max(1.0, chi2 / redundancy);
  const Eigen::MatrixXd covariance = update.covariance * solution.variance_factor;
  solution.covariance.setZero();
  if (p == 2) {
    // Every correspondence at one point: the translation only, the yaw undetermined.
    solution.covariance.topLeftCorner<2, 2>() = covariance;
    solution.covariance(2, 2) = std::numeric_limits<double>::infinity();
  } else {
    solution.covariance = covariance.topLeftCorner<3, 3>();
  }
  if (p == 4) solution.scale_sigma = std::sqrt(covariance(3, 3));
  return solution;
}

}  // namespace mosaicloc::tracking
