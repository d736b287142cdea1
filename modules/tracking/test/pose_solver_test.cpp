#include <algorithm>
#include <cstdint>
#include <numbers>
#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include "mosaicloc/tracking/pose_solver.hpp"
#include "tracking_test_support.hpp"

namespace mosaicloc::tracking {
namespace {

// Central differences of `residual` (N parameters, 2 x N row-major Jacobian) against its
// analytic Jacobian at random correspondences, poses (with N = 4 the scale drawn near 1) and
// relative sigmas.
template <int N, typename Residual>
void ExpectJacobianMatchesNumeric(Residual residual, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-100.0, 100.0);
  for (int trial = 0; trial < 20; ++trial) {
    Correspondence c;
    c.camera_mm = {u(rng), u(rng)};
    c.world_mm = {u(rng), u(rng)};
    double pose[N] = {u(rng), u(rng), u(rng) * 0.03};
    if (N == 4) pose[N - 1] = 1.0 + u(rng) * 1e-3;
    const double scale = 0.5 + std::abs(u(rng)) / 100.0;
    double r[2], j[2 * N];
    residual(pose, c, scale, r, j);
    for (int p = 0; p < N; ++p) {
      const double h = 1e-6;
      double plus[N], minus[N];
      std::copy(pose, pose + N, plus);
      std::copy(pose, pose + N, minus);
      plus[p] += h;
      minus[p] -= h;
      double rp[2], rm[2];
      residual(plus, c, scale, rp, nullptr);
      residual(minus, c, scale, rm, nullptr);
      for (int k = 0; k < 2; ++k) {
        EXPECT_NEAR(j[k * N + p], (rp[k] - rm[k]) / (2 * h), 1e-6) << "residual " << k << " parameter " << p;
      }
    }
  }
}

TEST(PoseSolver, AnalyticJacobianMatchesNumeric) { ExpectJacobianMatchesNumeric<3>(PlanarResidual, 8); }

TEST(PoseSolver, SimilarityJacobianMatchesNumeric) { ExpectJacobianMatchesNumeric<4>(SimilarityResidual, 18); }

std::vector<Correspondence> MakeCorrespondences(const Pose2& truth, int n, double noise_mm, std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-80.0, 80.0);
  std::normal_distribution<double> g(0.0, noise_mm);
  std::vector<Correspondence> cs;
  for (int i = 0; i < n; ++i) {
    Correspondence c;
    c.camera_mm = {u(*rng), u(*rng) * 0.75};
    c.world_mm = truth * c.camera_mm + Eigen::Vector2d(g(*rng), g(*rng));
    c.sigma_mm = std::max(noise_mm, 1e-6);
    cs.push_back(c);
  }
  return cs;
}

TEST(PoseSolver, ThirtyPercentOutliersDoNotMoveThePose) {
  std::mt19937 rng(9);
  const Pose2 truth(1234.5, -678.9, 0.7);
  std::vector<Correspondence> cs = MakeCorrespondences(truth, 20, 0.0, &rng);
  const PoseSolution clean = SolvePlanarPose(cs, Pose2(1234.0, -679.5, 0.69), PoseSolverOptions{});
  ASSERT_TRUE(clean.ok());
  std::uniform_real_distribution<double> wild(-5.0, 5.0);
  for (int i = 0; i < 6; ++i)
    cs[static_cast<std::size_t>(3 * i)].world_mm += Eigen::Vector2d(wild(rng), wild(rng)) + Eigen::Vector2d(1.0, 0.0);
  const PoseSolution solution = SolvePlanarPose(cs, Pose2(1234.0, -679.5, 0.69), PoseSolverOptions{});
  ASSERT_TRUE(solution.ok()) << ToString(solution.failure);
  EXPECT_LT(Distance(solution.world_from_camera, truth), 0.01);
  EXPECT_LT(std::abs(YawDifference(solution.world_from_camera, truth)), 1e-5);
  EXPECT_EQ(solution.inliers, 14);
  for (int i = 0; i < 6; ++i) EXPECT_FALSE(solution.inlier[static_cast<std::size_t>(3 * i)]);
}

TEST(PoseSolver, CovarianceFollowsTheNoise) {
  std::mt19937 rng(10);
  const Pose2 truth(10.0, 20.0, -0.2);
  // Empirical scatter over repeated noisy solves against the reported covariance.
  const double noise_mm = 0.01;
  double sum_sq = 0.0, reported = 0.0;
  const int trials = 200;
  for (int t = 0; t < trials; ++t) {
    const std::vector<Correspondence> cs = MakeCorrespondences(truth, 8, noise_mm, &rng);
    const PoseSolution s = SolvePlanarPose(cs, truth, PoseSolverOptions{});
    ASSERT_TRUE(s.ok());
    sum_sq += std::pow(s.world_from_camera.x_mm() - truth.x_mm(), 2);
    reported += s.covariance(0, 0);
  }
  const double ratio = std::sqrt(sum_sq / trials) / std::sqrt(reported / trials);
  EXPECT_NEAR(ratio, 1.0, 0.2);
}

// Templates that scatter five times more than their sigmas claim: the a-posteriori variance
// factor brings the covariance to the scatter; without it the covariance is five times
// overconfident. Templates as good as they claim are left as they are (the factor is >= 1).
TEST(PoseSolver, PosteriorVarianceFollowsTheScatter) {
  const Pose2 truth(10.0, 20.0, -0.2);
  const auto ratio = [&](double noise_mm, double claimed_mm, bool posterior) {
    std::mt19937 rng(11);
    PoseSolverOptions options;
    options.posterior_variance = posterior;
    options.outlier_threshold_mm = 1.0;
    options.loss = RobustLoss::kNone;
    double sum_sq = 0.0, reported = 0.0;
    const int trials = 300;
    for (int t = 0; t < trials; ++t) {
      std::vector<Correspondence> cs = MakeCorrespondences(truth, 12, noise_mm, &rng);
      for (Correspondence& c : cs) c.sigma_mm = claimed_mm;
      const PoseSolution s = SolvePlanarPose(cs, truth, options);
      EXPECT_TRUE(s.ok());
      EXPECT_GE(s.variance_factor, 1.0);
      if (!posterior) {
        EXPECT_EQ(s.variance_factor, 1.0);
      }
      sum_sq += std::pow(s.world_from_camera.x_mm() - truth.x_mm(), 2);
      reported += s.covariance(0, 0);
    }
    return std::sqrt(sum_sq / trials) / std::sqrt(reported / trials);
  };
  EXPECT_GT(ratio(0.05, 0.01, false), 4.0);
  EXPECT_NEAR(ratio(0.05, 0.01, true), 1.0, 0.2);
  // Honest sigmas: the factor's chi-square scatter above 1 inflates a little, never shrinks.
  const double honest = ratio(0.01, 0.01, true);
  EXPECT_GT(honest, 0.7);
  EXPECT_LE(honest, 1.05);
}

// One correspondence as a Ceres cost, for comparisons with ceres::Solve and ceres::Covariance.
class PlanarCeresCost final : public ceres::SizedCostFunction<2, 3> {
 public:
  explicit PlanarCeresCost(const Correspondence& c) : c_(c) {}
  bool Evaluate(double const* const* p, double* r, double** j) const override {
    PlanarResidual(p[0], c_, 1.0, r, j != nullptr ? j[0] : nullptr);
    return true;
  }

 private:
  Correspondence c_;
};

ceres::LossFunction* CeresLoss(RobustLoss loss, double scale) {
  if (loss == RobustLoss::kHuber) return new ceres::HuberLoss(scale);
  if (loss == RobustLoss::kCauchy) return new ceres::CauchyLoss(scale);
  return nullptr;
}

// The reweighted rounds reach the optimum ceres::Solve reaches on the same robust problem,
// with a quarter of the correspondences off by several loss scales.
TEST(PoseSolver, OptimumEqualsCeresSolve) {
  std::mt19937 rng(15);
  const Pose2 truth(-812.0, 95.0, 1.1);
  for (const RobustLoss loss : {RobustLoss::kNone, RobustLoss::kHuber, RobustLoss::kCauchy}) {
    PoseSolverOptions options;
    options.estimate_scale = false;  // the rigid formulation, as the Ceres problem states it
    options.loss = loss;
    options.outlier_threshold_mm = 10.0;  // keep every correspondence: compare the robust solve itself
    std::vector<Correspondence> cs = MakeCorrespondences(truth, 12, 0.02, &rng);
    for (std::size_t i = 0; i < cs.size(); i += 4) cs[i].world_mm += Eigen::Vector2d(0.3, -0.2);
    const Pose2 start(-811.6, 95.3, 1.098);
    const PoseSolution s = SolvePlanarPose(cs, start, options);
    ASSERT_TRUE(s.ok()) << ToString(s.failure);
    double pose[3] = {start.x_mm(), start.y_mm(), start.yaw_rad()};
    ceres::Problem problem;
    for (const Correspondence& c : cs) {
      problem.AddResidualBlock(new PlanarCeresCost(c), CeresLoss(loss, options.loss_scale_mm), pose);
    }
    ceres::Solver::Options solver_options;
    solver_options.function_tolerance = solver_options.parameter_tolerance = 1e-14;
    solver_options.gradient_tolerance = 1e-16;
    solver_options.max_num_iterations = 200;
    solver_options.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(solver_options, &problem, &summary);
    // The rounds stop once a round moves the position by under 10 nm: a nanometre from the
    // fixed point.
    EXPECT_NEAR(s.world_from_camera.x_mm(), pose[0], 2e-6) << static_cast<int>(loss);
    EXPECT_NEAR(s.world_from_camera.y_mm(), pose[1], 2e-6) << static_cast<int>(loss);
    EXPECT_NEAR(s.world_from_camera.yaw_rad(), pose[2], 2e-8) << static_cast<int>(loss);
  }
}

// The covariance is ceres::Covariance's on the same problem at the solution: residuals near
// the loss scale, so the robust loss's correction of the Jacobian counts.
TEST(PoseSolver, CovarianceEqualsCeresCovariance) {
  std::mt19937 rng(14);
  const Pose2 truth(321.0, -45.0, 0.4);
  for (const RobustLoss loss : {RobustLoss::kNone, RobustLoss::kHuber, RobustLoss::kCauchy}) {
    PoseSolverOptions options;
    options.estimate_scale = false;  // the rigid formulation, as the Ceres problem states it
    options.loss = loss;
    options.loss_scale_mm = 0.02;
    options.outlier_threshold_mm = 1.0;  // keep every correspondence
    const std::vector<Correspondence> cs = MakeCorrespondences(truth, 7, 0.03, &rng);
    const PoseSolution s = SolvePlanarPose(cs, truth, options);
    ASSERT_TRUE(s.ok());
    ASSERT_EQ(s.inliers, 7);
    double pose[3] = {s.world_from_camera.x_mm(), s.world_from_camera.y_mm(), s.world_from_camera.yaw_rad()};
    ceres::Problem problem;
    for (const Correspondence& c : cs) {
      problem.AddResidualBlock(new PlanarCeresCost(c), CeresLoss(loss, options.loss_scale_mm), pose);
    }
    ceres::Covariance::Options covariance_options;
    covariance_options.algorithm_type = ceres::DENSE_SVD;
    ceres::Covariance covariance(covariance_options);
    const std::vector<std::pair<const double*, const double*>> blocks = {{pose, pose}};
    ASSERT_TRUE(covariance.Compute(blocks, &problem));
    Eigen::Matrix<double, 3, 3, Eigen::RowMajor> expected;
    ASSERT_TRUE(covariance.GetCovarianceBlock(pose, pose, expected.data()));
    // Every sigma is the same, so the solver's unit is sigma^2.
    const Eigen::Matrix3d got = s.covariance / (0.03 * 0.03);
    EXPECT_LT((got - expected).norm(), 1e-9 * expected.norm()) << static_cast<int>(loss) << "\n"
                                                               << got << "\n" << expected;
  }
}

// Without the covariance the solve is the same; the covariance says it was not computed.
TEST(PoseSolver, SkippingTheCovarianceLeavesThePose) {
  std::mt19937 rng(12);
  const Pose2 truth(-4.0, 7.0, 0.3);
  const std::vector<Correspondence> cs = MakeCorrespondences(truth, 6, 0.01, &rng);
  PoseSolverOptions options;
  const PoseSolution with = SolvePlanarPose(cs, Pose2(-3.9, 7.05, 0.29), options);
  options.compute_covariance = false;
  const PoseSolution without = SolvePlanarPose(cs, Pose2(-3.9, 7.05, 0.29), options);
  ASSERT_TRUE(with.ok());
  ASSERT_TRUE(without.ok());
  EXPECT_EQ(with.world_from_camera.x_mm(), without.world_from_camera.x_mm());
  EXPECT_EQ(with.world_from_camera.y_mm(), without.world_from_camera.y_mm());
  EXPECT_EQ(with.world_from_camera.yaw_rad(), without.world_from_camera.yaw_rad());
  EXPECT_EQ(with.inlier, without.inlier);
  EXPECT_TRUE(with.covariance.allFinite());
  EXPECT_TRUE(without.covariance.array().isNaN().all());
}

// Correspondences all at one point of the frame fix the translation but not the yaw: the
// covariance says the yaw is unknown rather than exact.
TEST(PoseSolver, CorrespondencesAtOnePointLeaveTheYawUndetermined) {
  const Pose2 truth(5.0, -3.0, 0.1);
  std::vector<Correspondence> cs(4);
  for (Correspondence& c : cs) {
    c.camera_mm = {12.0, -7.0};
    c.world_mm = truth * c.camera_mm;
    c.sigma_mm = 0.001;
  }
  const PoseSolution s = SolvePlanarPose(cs, Pose2(5.1, -3.1, 0.1), PoseSolverOptions{});
  ASSERT_TRUE(s.ok()) << ToString(s.failure);
  EXPECT_LT((s.world_from_camera * cs[0].camera_mm - cs[0].world_mm).norm(), 1e-6);
  EXPECT_TRUE(std::isinf(s.covariance(2, 2))) << s.covariance;
  // Two distinct points determine it, with a finite variance.
  cs[1].camera_mm = {-30.0, 20.0};
  cs[1].world_mm = truth * cs[1].camera_mm;
  const PoseSolution two = SolvePlanarPose(cs, Pose2(5.1, -3.1, 0.1), PoseSolverOptions{});
  ASSERT_TRUE(two.ok());
  EXPECT_TRUE(two.covariance.allFinite()) << two.covariance;
  EXPECT_GT(two.covariance(2, 2), 0.0);
}

// A camera 1 % higher than calibrated: its points are 1 % farther out than camera_mm says.
// The rigid fit is pulled off; the similarity fit finds the pose and the scale.
TEST(PoseSolver, ScaleIsEstimatedWhereAsked) {
  std::mt19937 rng(31);
  const Pose2 truth(512.25, -77.5, -0.4);
  const double k = 1.01;
  std::vector<Correspondence> cs = MakeCorrespondences(truth, 8, 0.002, &rng);
  for (Correspondence& c : cs) c.world_mm = truth * (k * c.camera_mm) + (c.world_mm - truth * c.camera_mm);
  PoseSolverOptions options;
  options.estimate_scale = false;
  options.outlier_threshold_mm = 5.0;  // the rigid fit's residuals are up to a millimetre
  const PoseSolution rigid = SolvePlanarPose(cs, Pose2(512.0, -77.0, -0.39), options);
  ASSERT_TRUE(rigid.ok());
  EXPECT_FALSE(rigid.scale_estimated);
  EXPECT_EQ(rigid.scale, 1.0);
  EXPECT_GT(rigid.rms_residual_mm, 0.1);
  options.estimate_scale = true;
  const PoseSolution similar = SolvePlanarPose(cs, Pose2(512.0, -77.0, -0.39), options);
  ASSERT_TRUE(similar.ok());
  ASSERT_TRUE(similar.scale_estimated);
  EXPECT_NEAR(similar.scale, k, 1e-4);
  EXPECT_GT(similar.scale_sigma, 0.0);
  EXPECT_LT(similar.scale_sigma, 1e-3);
  EXPECT_NEAR(similar.world_from_camera.x_mm(), truth.x_mm(), 0.005);
  EXPECT_NEAR(similar.world_from_camera.y_mm(), truth.y_mm(), 0.005);
  EXPECT_NEAR(similar.world_from_camera.yaw_rad(), truth.yaw_rad(), 1e-4);
  EXPECT_LT(similar.rms_residual_mm, 0.01);
  // Two points of the frame leave no check on the scale: it is held.
  const std::vector<Correspondence> two(cs.begin(), cs.begin() + 2);
  options.min_inliers = 2;
  const PoseSolution held = SolvePlanarPose(two, Pose2(512.0, -77.0, -0.39), options);
  ASSERT_TRUE(held.ok());
  EXPECT_FALSE(held.scale_estimated);
  EXPECT_EQ(held.scale, 1.0);
}

// The tilted pinhole's Jacobian (by automatic differentiation) against central differences.
TEST(PoseSolver, TiltJacobianMatchesNumeric) {
  std::mt19937 rng(28);
  std::uniform_real_distribution<double> u(-100.0, 100.0);
  for (int trial = 0; trial < 20; ++trial) {
    Correspondence c;
    c.camera_mm = {u(rng), u(rng)};
    c.world_mm = {u(rng), u(rng)};
    const double pose[6] = {u(rng), u(rng), u(rng) * 0.03, 1.0 + u(rng) * 1e-3, u(rng) * 2e-4, u(rng) * 2e-4};
    double r[2], j[12];
    TiltResidual(pose, c, 0.8, 200.0, r, j);
    for (int p = 0; p < 6; ++p) {
      const double h = 1e-6;
      double plus[6], minus[6];
      std::copy(pose, pose + 6, plus);
      std::copy(pose, pose + 6, minus);
      plus[p] += h;
      minus[p] -= h;
      double rp[2], rm[2];
      TiltResidual(plus, c, 0.8, 200.0, rp, nullptr);
      TiltResidual(minus, c, 0.8, 200.0, rm, nullptr);
      for (int k = 0; k < 2; ++k) {
        EXPECT_NEAR(j[k * 6 + p], (rp[k] - rm[k]) / (2 * h), 1e-5) << "residual " << k << " parameter " << p;
      }
    }
  }
  // Untilted, it is the similarity.
  Correspondence c;
  c.camera_mm = {31.0, -47.0};
  c.world_mm = {5.0, 6.0};
  const double pose[6] = {1.0, 2.0, 0.3, 1.004, 0.0, 0.0};
  double tilted[2], similar[2];
  TiltResidual(pose, c, 1.0, 200.0, tilted, nullptr);
  SimilarityResidual(pose, c, 1.0, similar, nullptr);
  EXPECT_NEAR(tilted[0], similar[0], 1e-12);
  EXPECT_NEAR(tilted[1], similar[1], 1e-12);
}

// A pinhole 203 mm over a flat floor, pitched and rolled by a few tenths of a degree, its rays
// through a grid of the view cast onto the floor: the solve finds the image centre's floor
// point, the yaw, the height and the tilt the rays were cast with.
TEST(PoseSolver, TiltIsEstimatedFromAPinholesRays) {
  const double h = 200.0;
  const double height = 203.0, tilt_x = 0.004, tilt_y = -0.006, yaw = 0.8;
  const Eigen::Matrix3d world_from_camera = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                                             Eigen::AngleAxisd(tilt_x, Eigen::Vector3d::UnitX()) *
                                             Eigen::AngleAxisd(tilt_y, Eigen::Vector3d::UnitY()))
                                                .toRotationMatrix();
  const Eigen::Vector3d lens(1500.0, -300.0, 0.0);
  const auto floor_point = [&](const Eigen::Vector2d& p) {
    const Eigen::Vector3d ray = world_from_camera * Eigen::Vector3d(p.x() / h, p.y() / h, -1.0);
    return Eigen::Vector2d(lens.head<2>() + height / -ray.z() * ray.head<2>());
  };
  std::vector<Correspondence> cs;
  for (int i = 0; i < 5; ++i) {
    for (int j = 0; j < 4; ++j) {
      Correspondence c;
      c.camera_mm = {-70.0 + 35.0 * i, -52.5 + 35.0 * j};
      c.world_mm = floor_point(c.camera_mm);
      c.sigma_mm = 0.005;
      cs.push_back(c);
    }
  }
  const Eigen::Vector2d centre = floor_point(Eigen::Vector2d::Zero());
  PoseSolverOptions options;
  options.camera_height_mm = h;
  const PoseSolution similar = SolvePlanarPose(cs, Pose2(centre.x() + 0.5, centre.y(), yaw), options);
  ASSERT_TRUE(similar.ok());
  EXPECT_FALSE(similar.tilt_estimated);
  EXPECT_GT(similar.rms_residual_mm, 0.05) << "the keystone is a residual of the similarity";
  options.estimate_tilt = true;
  const PoseSolution solution = SolvePlanarPose(cs, Pose2(centre.x() + 0.5, centre.y(), yaw), options);
  ASSERT_TRUE(solution.ok());
  ASSERT_TRUE(solution.tilt_estimated);
  EXPECT_LT(solution.rms_residual_mm, 1e-6);
  EXPECT_NEAR(solution.world_from_camera.x_mm(), centre.x(), 1e-6);
  EXPECT_NEAR(solution.world_from_camera.y_mm(), centre.y(), 1e-6);
  EXPECT_NEAR(solution.world_from_camera.yaw_rad(), yaw, 1e-4);
  EXPECT_NEAR(solution.scale * h, height, 1e-4);
  // The floor's normal in camera axes is (-tan tilt_y, tan tilt_x, 1), normalized.
  const Eigen::Vector3d n = world_from_camera.transpose() * Eigen::Vector3d::UnitZ();
  EXPECT_NEAR(solution.tilt_x_rad, std::atan2(n.y(), n.z()), 1e-6);
  EXPECT_NEAR(solution.tilt_y_rad, std::atan2(-n.x(), n.z()), 1e-6);
  EXPECT_GT(solution.tilt_sigma_rad, 0.0);
  EXPECT_LT(solution.tilt_sigma_rad, 1e-3);
  // Too few points for the tilt: the similarity.
  const std::vector<Correspondence> few(cs.begin(), cs.begin() + 5);
  EXPECT_FALSE(SolvePlanarPose(few, Pose2(centre.x(), centre.y(), yaw), options).tilt_estimated);
}

// The same pinhole seen by six templates on one side of the view, too few for the tilt: a
// level camera's similarity turns and shifts with the tilt as they lie. Held at the tilt a
// prediction gives, the pose is the true one; held level but as uncertain as the tilt is
// large, the covariance covers the error.
TEST(PoseSolver, ATiltHeldFromAPredictionIsSolvedThroughAndCarriedInTheCovariance) {
  const double h = 200.0;
  const double tilt_x = 0.004, tilt_y = -0.006, yaw = 0.8;
  const Eigen::Matrix3d world_from_camera = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                                             Eigen::AngleAxisd(tilt_x, Eigen::Vector3d::UnitX()) *
                                             Eigen::AngleAxisd(tilt_y, Eigen::Vector3d::UnitY()))
                                                .toRotationMatrix();
  const Eigen::Vector3d lens(1500.0, -300.0, 0.0);
  const auto floor_point = [&](const Eigen::Vector2d& p) {
    const Eigen::Vector3d ray = world_from_camera * Eigen::Vector3d(p.x() / h, p.y() / h, -1.0);
    return Eigen::Vector2d(lens.head<2>() + h / -ray.z() * ray.head<2>());
  };
  std::vector<Correspondence> cs;
  for (int i = 0; i < 2; ++i) {
    for (int j = 0; j < 3; ++j) {
      Correspondence c;
      c.camera_mm = {40.0 + 30.0 * i, -40.0 + 40.0 * j};
      c.world_mm = floor_point(c.camera_mm);
      c.sigma_mm = 0.005;
      cs.push_back(c);
    }
  }
  const Eigen::Vector2d centre = floor_point(Eigen::Vector2d::Zero());
  const Eigen::Vector3d n = world_from_camera.transpose() * Eigen::Vector3d::UnitZ();
  PoseSolverOptions options;
  options.camera_height_mm = h;
  options.estimate_tilt = true;
  const auto error = [&](const PoseSolution& s) {
    return Eigen::Vector3d(s.world_from_camera.x_mm() - centre.x(), s.world_from_camera.y_mm() - centre.y(),
                           s.world_from_camera.yaw_rad() - yaw);
  };
  const PoseSolution level = SolvePlanarPose(cs, Pose2(centre.x(), centre.y(), yaw), options);
  ASSERT_TRUE(level.ok());
  EXPECT_FALSE(level.tilt_estimated);
  RecordProperty("level_error_mm", std::to_string(error(level).head<2>().norm()));
  RecordProperty("level_yaw_error_rad", std::to_string(error(level).z()));
  EXPECT_GT(error(level).head<2>().norm(), 0.03) << "the tilt, not measured, is an error";

  options.held_tilt_x_rad = std::atan2(n.y(), n.z());
  options.held_tilt_y_rad = std::atan2(-n.x(), n.z());
  const PoseSolution held = SolvePlanarPose(cs, Pose2(centre.x(), centre.y(), yaw), options);
  ASSERT_TRUE(held.ok());
  EXPECT_FALSE(held.tilt_estimated);
  EXPECT_EQ(held.tilt_x_rad, options.held_tilt_x_rad);
  EXPECT_LT(held.rms_residual_mm, 1e-6);
  EXPECT_LT(error(held).head<2>().norm(), 1e-6);
  EXPECT_NEAR(held.world_from_camera.yaw_rad(), yaw, 1e-4);  // the plane's axes, not these Euler angles' yaw

  options.held_tilt_x_rad = options.held_tilt_y_rad = 0.0;
  options.held_tilt_sigma_rad = 0.006;
  const PoseSolution uncertain = SolvePlanarPose(cs, Pose2(centre.x(), centre.y(), yaw), options);
  ASSERT_TRUE(uncertain.ok());
  EXPECT_LT((uncertain.world_from_camera.translation_mm() - level.world_from_camera.translation_mm()).norm(), 1e-9)
      << "the uncertainty moves no estimate";
  for (int k = 0; k < 3; ++k) {
    EXPECT_GT(uncertain.covariance(k, k), 100.0 * level.covariance(k, k));
    EXPECT_LT(std::abs(error(uncertain)(k)), 3.0 * std::sqrt(uncertain.covariance(k, k))) << "component " << k;
  }
}

TEST(PoseSolver, SaysWhyItFailed) {
  std::mt19937 rng(11);
  const std::vector<Correspondence> two = MakeCorrespondences(Pose2(), 2, 0.0, &rng);
  EXPECT_EQ(SolvePlanarPose(two, Pose2(), PoseSolverOptions{}).failure, PoseFailure::kTooFewInliers);
  // Three correspondences that disagree by millimetres: nothing is an inlier of anything.
  std::vector<Correspondence> scattered = MakeCorrespondences(Pose2(), 3, 0.0, &rng);
  scattered[0].world_mm.x() += 3.0;
  scattered[1].world_mm.y() -= 3.0;
  EXPECT_EQ(SolvePlanarPose(scattered, Pose2(), PoseSolverOptions{}).failure, PoseFailure::kTooFewInliers);
}

// The founding paper's Kalman observer and the solver on clean data: with the solver's loss off
// (both then minimise the same squares) the same pose, scale and covariance, the observer's weak
// prior moving neither measurably; against the default Cauchy loss, which weighs residuals of a
// fifth of its scale a little less, within half a standard deviation and 15 % in variance.
TEST(KalmanObserver, AgreesWithTheSolverOnCleanData) {
  std::mt19937 rng(21);
  PoseSolverOptions observer;
  observer.method = PoseMethod::kKalmanObserver;
  for (const bool scale : {false, true}) {
    for (int trial = 0; trial < 20; ++trial) {
      const Pose2 truth(500.0 + 10.0 * trial, -300.0, 0.05 * trial);
      std::vector<Correspondence> cs = MakeCorrespondences(truth, 20, 0.01, &rng);
      if (scale) {
        for (Correspondence& c : cs) c.camera_mm /= 1.004;  // the camera 0.4 % higher than calibrated
      }
      const Pose2 start = truth * Pose2(0.8, -0.6, 0.004);
      PoseSolverOptions solver;
      solver.estimate_scale = observer.estimate_scale = scale;
      const PoseSolution robust = SolvePlanarPose(cs, start, solver);
      solver.loss = RobustLoss::kNone;
      const PoseSolution a = SolvePlanarPose(cs, start, solver);
      const PoseSolution b = SolvePlanarPose(cs, start, observer);
      ASSERT_TRUE(a.ok() && b.ok() && robust.ok()) << ToString(a.failure) << " / " << ToString(b.failure);
      EXPECT_LT(Distance(robust.world_from_camera, b.world_from_camera),
                0.5 * std::sqrt(robust.covariance(0, 0) + robust.covariance(1, 1)));
      EXPECT_NEAR(b.covariance(0, 0) / robust.covariance(0, 0), 1.0, 0.15);
      EXPECT_EQ(b.inliers, 20);
      EXPECT_LT(Distance(a.world_from_camera, b.world_from_camera), 1e-5);
      EXPECT_LT(std::abs(YawDifference(a.world_from_camera, b.world_from_camera)), 1e-7);
      EXPECT_EQ(b.scale_estimated, scale);
      EXPECT_NEAR(a.scale, b.scale, 1e-7);
      if (scale) {
        EXPECT_NEAR(b.scale_sigma / a.scale_sigma, 1.0, 0.01);
      }
      EXPECT_LT(Distance(b.world_from_camera, truth), 0.02);
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(b.covariance(k, k) / a.covariance(k, k), 1.0, 0.01) << k;
    }
  }
}

// A false match among 20 (a template that matched 0.5 to 3 mm away): the observer finds it and
// leaves it out, as the robust solver does, and the pose is the clean one's.
TEST(KalmanObserver, LeavesAFalseMatchAmongTwentyOut) {
  std::mt19937 rng(22);
  std::uniform_real_distribution<double> away(0.5, 3.0), direction(-std::numbers::pi, std::numbers::pi);
  PoseSolverOptions observer;
  observer.method = PoseMethod::kKalmanObserver;
  for (int trial = 0; trial < 50; ++trial) {
    const Pose2 truth(100.0, 200.0, 0.3);
    std::vector<Correspondence> cs = MakeCorrespondences(truth, 20, 0.01, &rng);
    const PoseSolution clean = SolvePlanarPose(cs, truth, observer);
    const std::size_t bad = static_cast<std::size_t>(trial % 20);
    const double a = direction(rng);
    cs[bad].world_mm += away(rng) * Eigen::Vector2d(std::cos(a), std::sin(a));
    const PoseSolution b = SolvePlanarPose(cs, truth * Pose2(0.5, 0.5, 0.002), observer);
    const PoseSolution solver = SolvePlanarPose(cs, truth * Pose2(0.5, 0.5, 0.002), PoseSolverOptions{});
    ASSERT_TRUE(b.ok() && solver.ok());
    EXPECT_FALSE(b.inlier[bad]);
    EXPECT_EQ(b.inliers, 19);
    EXPECT_FALSE(solver.inlier[bad]);
    EXPECT_LT(Distance(b.world_from_camera, truth), 0.02);
    EXPECT_LT(Distance(b.world_from_camera, solver.world_from_camera),
              0.5 * std::sqrt(solver.covariance(0, 0) + solver.covariance(1, 1)));
    EXPECT_GT(Distance(b.world_from_camera, clean.world_from_camera), 0.0);  // one fewer measurement
  }
}

TEST(KalmanObserver, SaysWhyItFailedAndRefusesTheTilt) {
  std::mt19937 rng(23);
  PoseSolverOptions observer;
  observer.method = PoseMethod::kKalmanObserver;
  std::vector<Correspondence> scattered = MakeCorrespondences(Pose2(), 3, 0.0, &rng);
  scattered[0].world_mm.x() += 3.0;
  scattered[1].world_mm.y() -= 3.0;
  EXPECT_EQ(SolvePlanarPose(scattered, Pose2(), observer).failure, PoseFailure::kTooFewInliers);
  // Every correspondence at one point: the translation, the yaw undetermined.
  std::vector<Correspondence> one = MakeCorrespondences(Pose2(5.0, 6.0, 0.1), 1, 0.0, &rng);
  one.push_back(one[0]);
  one.push_back(one[0]);
  const PoseSolution at_one = SolvePlanarPose(one, Pose2(5.2, 5.9, 0.1), observer);
  ASSERT_TRUE(at_one.ok());
  EXPECT_LT((at_one.world_from_camera * one[0].camera_mm - one[0].world_mm).norm(), 1e-6);
  EXPECT_TRUE(std::isinf(at_one.covariance(2, 2)));
  std::string why;
  observer.estimate_tilt = true;
  EXPECT_FALSE(observer.Check(&why));
  EXPECT_NE(why.find("not the tilt"), std::string::npos) << why;
  EXPECT_STREQ(ToString(PoseMethod::kKalmanObserver), "kalman-observer");
}

}  // namespace
}  // namespace mosaicloc::tracking
