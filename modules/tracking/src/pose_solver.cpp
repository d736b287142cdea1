#include "mosaicloc/tracking/pose_solver.hpp"
#include "pose_solver_internal.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include <Eigen/Eigenvalues>
#include <ceres/ceres.h>
#include <ceres/jet.h>
#include <ceres/tiny_solver.h>

namespace mosaicloc::tracking {
namespace {

// Residual of one correspondence (p in the camera floor frame C, w in the world, mm), with
// the image scale k as a fourth parameter where it is estimated (1 where it is not):
//
//   r(x, y, yaw, k) = ( k R(yaw) p + (x, y) - w ) / s,      R(yaw) = [cos -sin; sin cos],
//
// s = the correspondence's relative standard deviation (sigma_i / median sigma), so r stays
// in mm for a typical correspondence and the loss scale keeps its meaning. Jacobian:
//   dr/dx = (1, 0) / s,  dr/dy = (0, 1) / s,  dr/dyaw = k R'(yaw) p / s,  dr/dk = R(yaw) p / s,
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

// The residual of the model with `free` parameters at pose (x, y, yaw, k, a, b): the tilted
// pinhole with all six free or a tilt held, else the similarity (k and a level camera held).
// The Jacobian is 2 x 6, row-major, zero in the tilt's columns for the similarity.
void ModelResidual(const double* pose, const Correspondence& c, double s, double height_mm, int free, double* r,
                   double* j) {
  if (free == 6 || pose[4] != 0.0 || pose[5] != 0.0) {
    TiltResidual(pose, c, s, height_mm, r, j);
    return;
  }
  double j4[8];
  SimilarityResidual(pose, c, s, r, j != nullptr ? j4 : nullptr);
  if (j == nullptr) return;
  for (int row = 0; row < 2; ++row) {
    for (int col = 0; col < 6; ++col) j[6 * row + col] = col < 4 ? j4[4 * row + col] : 0.0;
  }
}

// The used correspondences' residuals, each weighted by sqrt(w_i), as a ceres::TinySolver
// function of (x, y, yaw, k, a, b) (P = 6), (x, y, yaw, k) (P = 4), (x, y, yaw) with k held
// (P = 3), or (x, y) with the yaw held as well (P = 2); what is held keeps its start value.
// kParameters is P for the default (P = 4, the scale estimated), whose fixed-size solver is
// 20-30 % faster; Eigen::Dynamic serves the others with P at run time (a fixed-size
// TinySolver costs 8 s of compiling, twice that under the sanitizers).
template <int kParameters>
struct WeightedResiduals {
  using Scalar = double;
  enum { NUM_RESIDUALS = Eigen::Dynamic, NUM_PARAMETERS = kParameters };
  const std::vector<const Correspondence*>& cs;
  const std::vector<double>& scale;
  const std::vector<double>& root_weight;
  const double* held;  // the start pose (6)
  double height_mm;
  int P;  // the free parameters
  int NumResiduals() const { return static_cast<int>(2 * cs.size()); }
  int NumParameters() const { return P; }
  // (x, y, yaw, k, a, b) of the parameters x.
  void PoseOf(const double* x, double* pose) const {
    for (int p = 0; p < 6; ++p) pose[p] = p < P ? x[p] : held[p];
  }
  bool operator()(const double* x, double* residuals, double* jacobian) const {
    double pose[6];
    PoseOf(x, pose);
    const std::size_t n = 2 * cs.size();
    for (std::size_t i = 0; i < cs.size(); ++i) {
      double r[2], j[12];
      ModelResidual(pose, *cs[i], scale[i], height_mm, P, r, jacobian != nullptr ? j : nullptr);
      residuals[2 * i] = root_weight[i] * r[0];
      residuals[2 * i + 1] = root_weight[i] * r[1];
      if (jacobian == nullptr) continue;
      for (int p = 0; p < P; ++p) {  // column-major, n x P
        jacobian[static_cast<std::size_t>(p) * n + 2 * i] = root_weight[i] * j[p];
        jacobian[static_cast<std::size_t>(p) * n + 2 * i + 1] = root_weight[i] * j[6 + p];
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
template <int kParameters>
Solved SolveRounds(const std::vector<const Correspondence*>& cs, const std::vector<double>& scale, double* pose,
                   const PoseSolverOptions& options, int P) {
  using Residuals = WeightedResiduals<kParameters>;
  using Vector = Eigen::Matrix<double, kParameters, 1>;
  const std::unique_ptr<ceres::LossFunction> loss = LossOf(options);
  std::vector<double> root_weight(cs.size(), 1.0);
  double held[6];
  std::copy(pose, pose + 6, held);
  const Residuals residuals{cs, scale, root_weight, held, options.camera_height_mm, P};
  ceres::TinySolver<Residuals> solver;
  solver.options.max_num_iterations = options.max_iterations;
  solver.options.gradient_tolerance = 1e-14;
  solver.options.parameter_tolerance = 1e-12;
  solver.options.function_tolerance = 1e-12;
  Solved s;
  Vector x(P);
  for (int p = 0; p < P; ++p) x(p) = pose[p];
  for (int round = 0; round < options.max_iterations; ++round) {
    s.iterations = round + 1;
    double at[6];
    residuals.PoseOf(x.data(), at);
    for (std::size_t i = 0; i < cs.size(); ++i) {
      double r[2];
      ModelResidual(at, *cs[i], scale[i], options.camera_height_mm, P, r, nullptr);
      root_weight[i] = std::sqrt(LossWeight(loss.get(), r));
    }
    const Vector before = x;
    const auto& summary = solver.Solve(residuals, &x);
    if (summary.status == ceres::TinySolver<Residuals>::HIT_MAX_ITERATIONS || !x.allFinite()) break;
    // Without a loss the weights never change: one round is the solution. With one the rounds
    // approach the fixed point linearly, slowly where residuals are several loss scales: stop
    // when a round moves the position by under 10 nm and the yaw, scale and tilt by under 1e-7
    // (10 nm at the edge of the view), far below any fix's uncertainty.
    bool settled = std::abs(x(0) - before(0)) <= 1e-5 && std::abs(x(1) - before(1)) <= 1e-5;
    for (int p = 2; p < P; ++p) settled = settled && std::abs(x(p) - before(p)) <= 1e-7;
    if (!loss || settled) {
      s.converged = true;
      break;
    }
  }
  for (int p = 0; p < P; ++p) pose[p] = x(p);
  return s;
}

// Solves in place: `pose` (x, y, yaw, k, a, b) is both the start and the result; `free` of
// its parameters are estimated (2: the yaw, k and the tilt held, 3: k and the tilt held, 4:
// the tilt held, 6: all).
Solved Solve(const std::vector<Correspondence>& cs, const std::vector<bool>& use, const std::vector<double>& scale,
             double* pose, const PoseSolverOptions& options, int free) {
  std::vector<const Correspondence*> used;
  std::vector<double> used_scale;
  for (std::size_t i = 0; i < cs.size(); ++i) {
    if (!use[i]) continue;
    used.push_back(&cs[i]);
    used_scale.push_back(scale[i]);
  }
  return free == 4 ? SolveRounds<4>(used, used_scale, pose, options, 4)
                   : SolveRounds<Eigen::Dynamic>(used, used_scale, pose, options, free);
}

// How many parameters the used correspondences determine: the yaw needs two distinct points
// of the frame, the scale (when asked for) four, two more than it needs: with three, one
// biased match (a template across the edge of paint the map does not have) bends the scale
// and the position with it by millimetres and leaves no residual to show it; the tilt min_tilt_points.
int FreeParameters(const std::vector<Correspondence>& cs, const std::vector<bool>& use,
                   const PoseSolverOptions& options) {
  const std::size_t wanted =
      options.estimate_scale && options.estimate_tilt ? static_cast<std::size_t>(std::max(4, options.min_tilt_points)) : 4;
  const auto distinct = static_cast<std::size_t>(internal::DistinctPoints(cs, use, wanted));
  if (options.estimate_scale && options.estimate_tilt && distinct >= wanted) return 6;
  if (options.estimate_scale && distinct >= 4) return 4;
  return distinct >= 2 ? 3 : 2;
}

// The covariance of the pose at the solution, (J^T J)^-1 of the used residuals, as
// ceres::Covariance finds it: each residual's Jacobian carries the robust loss's correction,
// which for Huber and Cauchy (rho'' <= 0) is a factor sqrt(rho'(|r|^2)). Computed here because
// ceres::Covariance's set-up costs more than the whole solve of three parameters. False when
// J^T J is rank deficient (a direction the residuals do not determine).
// The inverse of the information's leading N x N block into *covariance's; false when it is
// rank deficient.
using Matrix6d = Eigen::Matrix<double, 6, 6>;

template <int N>
bool InvertInformation(const Matrix6d& information, Matrix6d* covariance) {
  const Eigen::Matrix<double, N, N> block = information.topLeftCorner<N, N>();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, N, N>> eigen(block);
  const Eigen::Matrix<double, N, 1> values = eigen.eigenvalues();  // ascending
  if (!(values(0) > 1e-14 * values(N - 1))) return false;
  covariance->topLeftCorner<N, N>() =
      eigen.eigenvectors() * values.cwiseInverse().asDiagonal() * eigen.eigenvectors().transpose();
  return true;
}

// The used residuals' information J^T W J at `pose` in all six parameters, of the model with
// `free` parameters (ModelResidual), each weighted by the loss's rho'.
Matrix6d Information(const std::vector<Correspondence>& cs, const std::vector<bool>& use,
                     const std::vector<double>& scale, const double* pose, const PoseSolverOptions& options,
                     int free) {
  const std::unique_ptr<ceres::LossFunction> loss = LossOf(options);
  Matrix6d information = Matrix6d::Zero();
  for (std::size_t i = 0; i < cs.size(); ++i) {
    if (!use[i]) continue;
    double r[2];
    Eigen::Matrix<double, 2, 6, Eigen::RowMajor> j;
    ModelResidual(pose, cs[i], scale[i], options.camera_height_mm, free, r, j.data());
    information += LossWeight(loss.get(), r) * j.transpose() * j;
  }
  return information;
}

// The covariance of the `free` leading parameters of (x, y, yaw, k, a, b), at least the
// first three.
bool PoseCovariance(const std::vector<Correspondence>& cs, const std::vector<bool>& use,
                    const std::vector<double>& scale, const double* pose, const PoseSolverOptions& options, int free,
                    Matrix6d* covariance) {
  const Matrix6d information = Information(cs, use, scale, pose, options, free);
  covariance->setZero();
  if (free == 6) return InvertInformation<6>(information, covariance);
  return free == 4 ? InvertInformation<4>(information, covariance) : InvertInformation<3>(information, covariance);
}

// How far a held tilt moves the solved (x, y, yaw): S S^T, with S = -(J_p^T W J_p)^-1 J_p^T W J_t
// the change of the `free` estimated parameters per unit change of the held tilt (tan, about
// each axis), at the solution; times the tilt's variance it is the pose's covariance the
// tilt's uncertainty adds.
Eigen::Matrix3d ConsideredTilt(const std::vector<Correspondence>& cs, const std::vector<bool>& use,
                               const std::vector<double>& scale, const double* pose, const PoseSolverOptions& options,
                               int free) {
  const Matrix6d information = Information(cs, use, scale, pose, options, 6);  // the tilted pinhole's Jacobian
  const Eigen::MatrixXd estimated = information.topLeftCorner(free, free);
  const Eigen::MatrixXd s = -estimated.ldlt().solve(information.block(0, 4, free, 2));
  Eigen::Matrix<double, 3, 2> pose_per_tilt = Eigen::Matrix<double, 3, 2>::Zero();  // a held yaw does not move
  pose_per_tilt.topRows(std::min(free, 3)) = s.topRows(std::min(free, 3));
  const Eigen::Matrix3d moved = pose_per_tilt * pose_per_tilt.transpose();
  return moved.allFinite() ? moved : Eigen::Matrix3d::Zero();
}

// TiltResidual's arithmetic for doubles or Jets.
template <typename T>
void TiltedResidual(const T* pose, const Correspondence& c, double s, double height_mm, T* residual) {
  using std::sqrt;
  using std::cos;
  using std::sin;
  const T& k = pose[3];
  const T norm = sqrt(pose[4] * pose[4] + pose[5] * pose[5] + T(1.0));
  const T n[3] = {-pose[5] / norm, pose[4] / norm, T(1.0) / norm};  // the floor's normal, camera axes
  const T distance = k * height_mm;                                  // lens to the plane, along n
  const double d[3] = {c.camera_mm.x() / height_mm, c.camera_mm.y() / height_mm, -1.0};
  // The ray's point X = tau d with n.X = -distance; the centre's X0 = tau0 (0, 0, -1).
  const T tau = -distance / (n[0] * d[0] + n[1] * d[1] + n[2] * d[2]);
  const T tau0 = distance / n[2];
  const T v[3] = {tau * d[0], tau * d[1], tau * d[2] + tau0};  // X - X0
  // The plane's axes: the camera's x projected onto it, and n x e1.
  T e1[3] = {T(1.0) - n[0] * n[0], -n[0] * n[1], -n[0] * n[2]};
  const T e1_norm = sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]);
  for (T& e : e1) e /= e1_norm;
  const T e2[3] = {n[1] * e1[2] - n[2] * e1[1], n[2] * e1[0] - n[0] * e1[2], n[0] * e1[1] - n[1] * e1[0]};
  const T qx = v[0] * e1[0] + v[1] * e1[1] + v[2] * e1[2];
  const T qy = v[0] * e2[0] + v[1] * e2[1] + v[2] * e2[2];
  const T cos_yaw = cos(pose[2]), sin_yaw = sin(pose[2]);
  residual[0] = (cos_yaw * qx - sin_yaw * qy + pose[0] - c.world_mm.x()) / s;
  residual[1] = (sin_yaw * qx + cos_yaw * qy + pose[1] - c.world_mm.y()) / s;
}

}  // namespace

void SimilarityResidual(const double* pose, const Correspondence& c, double scale, double* residual,
                        double* jacobian) {
  const double cos_yaw = std::cos(pose[2]), sin_yaw = std::sin(pose[2]), k = pose[3];
  const double px = c.camera_mm.x(), py = c.camera_mm.y();
  const double rx = cos_yaw * px - sin_yaw * py, ry = sin_yaw * px + cos_yaw * py;  // R p
  residual[0] = (k * rx + pose[0] - c.world_mm.x()) / scale;
  residual[1] = (k * ry + pose[1] - c.world_mm.y()) / scale;
  if (jacobian == nullptr) return;
  jacobian[0] = 1.0 / scale;
  jacobian[1] = 0.0;
  jacobian[2] = -k * ry / scale;
  jacobian[3] = rx / scale;
  jacobian[4] = 0.0;
  jacobian[5] = 1.0 / scale;
  jacobian[6] = k * rx / scale;
  jacobian[7] = ry / scale;
}

void TiltResidual(const double* pose, const Correspondence& c, double scale, double height_mm, double* residual,
                  double* jacobian) {
  if (jacobian == nullptr) {
    TiltedResidual(pose, c, scale, height_mm, residual);
    return;
  }
  using Jet = ceres::Jet<double, 6>;
  Jet at[6];
  for (int p = 0; p < 6; ++p) at[p] = Jet(pose[p], p);
  Jet r[2];
  TiltedResidual(at, c, scale, height_mm, r);
  for (int row = 0; row < 2; ++row) {
    residual[row] = r[row].a;
    for (int col = 0; col < 6; ++col) jacobian[6 * row + col] = r[row].v(col);
  }
}

void PlanarResidual(const double* pose, const Correspondence& c, double scale, double* residual,
                    double* jacobian) {
  const double similarity[4] = {pose[0], pose[1], pose[2], 1.0};
  double j[8];
  SimilarityResidual(similarity, c, scale, residual, jacobian != nullptr ? j : nullptr);
  if (jacobian == nullptr) return;
  for (int row = 0; row < 2; ++row) {
    for (int col = 0; col < 3; ++col) jacobian[3 * row + col] = j[4 * row + col];
  }
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
  if (min_tilt_points < 6) return fail("min_tilt_points must be >= 6");
  if (!(std::abs(held_tilt_x_rad) < 0.5 && std::abs(held_tilt_y_rad) < 0.5 && held_tilt_sigma_rad >= 0.0 &&
        held_tilt_sigma_rad < 0.5)) {
    return fail("held_tilt_x_rad and _y_rad must be within +-0.5 and held_tilt_sigma_rad in [0, 0.5)");
  }
  if (!(camera_height_mm > 0.0)) return fail("camera_height_mm must be > 0");
  if (!(observer_prior_sigma_mm > 0.0) || !(observer_prior_sigma_deg > 0.0) || !(observer_prior_sigma_scale > 0.0)) {
    return fail("observer_prior_sigma_mm, _deg and _scale must be > 0");
  }
  if (method == PoseMethod::kKalmanObserver && estimate_tilt) {
    return fail("method kalman-observer estimates x, y, yaw and the scale, not the tilt: estimate_tilt must be false");
  }
  return true;
}

const char* ToString(PoseMethod method) {
  switch (method) {
    case PoseMethod::kLeastSquares: return "least-squares";
    case PoseMethod::kKalmanObserver: return "kalman-observer";
  }
  return "unknown";
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

int internal::DistinctPoints(const std::vector<Correspondence>& cs, const std::vector<bool>& use, std::size_t enough) {
  std::vector<Eigen::Vector2d> distinct;
  for (std::size_t i = 0; i < cs.size() && distinct.size() < enough; ++i) {
    if (!use[i]) continue;
    const bool seen = std::any_of(distinct.begin(), distinct.end(), [&](const Eigen::Vector2d& p) {
      return (cs[i].camera_mm - p).squaredNorm() <= 1e-12;
    });
    if (!seen) distinct.push_back(cs[i].camera_mm);
  }
  return static_cast<int>(distinct.size());
}

PoseSolution internal::StartSolution(const std::vector<Correspondence>& correspondences, const core::Pose2& initial,
                                     int min_inliers) {
  PoseSolution solution;
  solution.world_from_camera = initial;
  const std::size_t n = correspondences.size();
  solution.inlier.assign(n, false);
  solution.residual_mm.assign(n, 0.0);
  if (n == 0 || static_cast<int>(n) < min_inliers) solution.failure = PoseFailure::kTooFewInliers;
  return solution;
}

PoseSolution SolvePlanarPose(const std::vector<Correspondence>& correspondences, const core::Pose2& initial,
                             const PoseSolverOptions& options) {
  if (options.method == PoseMethod::kKalmanObserver) return ObservePlanarPose(correspondences, initial, options);
  PoseSolution solution = internal::StartSolution(correspondences, initial, options.min_inliers);
  if (!solution.ok()) return solution;
  const std::size_t n = correspondences.size();
  std::vector<double> sigmas;
  sigmas.reserve(n);
  for (const Correspondence& c : correspondences) sigmas.push_back(std::max(c.sigma_mm, 1e-9));
  const double sigma_ref = Median(sigmas);
  std::vector<double> scale(n);
  for (std::size_t i = 0; i < n; ++i) scale[i] = sigmas[i] / sigma_ref;

  // The scale starts at 1 and the tilt at the one held, for the solve of it or to hold.
  const double held_a = std::tan(options.held_tilt_x_rad), held_b = std::tan(options.held_tilt_y_rad);
  double pose[6] = {initial.x_mm(), initial.y_mm(), initial.yaw_rad(), 1.0, held_a, held_b};
  std::vector<bool> use(n, true);
  int free = FreeParameters(correspondences, use, options);
  Solved solved = Solve(correspondences, use, scale, pose, options, free);

  // Outliers by their residual at the robust solution, then a clean solve on the inliers.
  auto residual_of = [&](std::size_t i, const double* at) {
    double r[2];
    ModelResidual(at, correspondences[i], 1.0, options.camera_height_mm, free, r, nullptr);
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
    free = FreeParameters(correspondences, use, options);
    pose[3] = 1.0;
    pose[4] = held_a;
    pose[5] = held_b;
    solved = Solve(correspondences, use, scale, pose, options, free);
  }
  solution.iterations = solved.iterations;
  solution.world_from_camera = core::Pose2(pose[0], pose[1], pose[2]);
  solution.scale = pose[3];
  solution.scale_estimated = free >= 4;
  solution.tilt_estimated = free == 6;
  solution.tilt_x_rad = std::atan(pose[4]);
  solution.tilt_y_rad = std::atan(pose[5]);
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
  Matrix6d unit;
  if (spread && PoseCovariance(correspondences, use, scale, pose, options, free, &unit)) {
    // With the scale (and the tilt) estimated, the pose's covariance is its marginal one.
    const int redundancy = 2 * inliers - free;
    if (options.posterior_variance && redundancy > 0) {
      double chi2 = 0.0;
      for (std::size_t i = 0; i < n; ++i) {
        if (use[i]) chi2 += std::pow(solution.residual_mm[i] / sigmas[i], 2);
      }
      solution.variance_factor = std::max(1.0, chi2 / redundancy);
    }
    unit *= solution.variance_factor;
    solution.covariance = unit.topLeftCorner<3, 3>() * sigma_ref * sigma_ref;
    if (free < 6 && options.held_tilt_sigma_rad > 0.0) {
      solution.covariance += ConsideredTilt(correspondences, use, scale, pose, options, free) *
                             options.held_tilt_sigma_rad * options.held_tilt_sigma_rad;
    }
    if (free >= 4) solution.scale_sigma = std::sqrt(unit(3, 3)) * sigma_ref;
    if (free == 6) solution.tilt_sigma_rad = std::sqrt(std::max(unit(4, 4), unit(5, 5))) * sigma_ref;
  } else {
    // One correspondence, or several at one point: translation only, the yaw undetermined.
    solution.covariance = Eigen::Matrix3d::Zero();
    solution.covariance(0, 0) = solution.covariance(1, 1) = sigma_ref * sigma_ref;
    solution.covariance(2, 2) = std::numeric_limits<double>::infinity();
  }
  return solution;
}

}  // namespace mosaicloc::tracking
