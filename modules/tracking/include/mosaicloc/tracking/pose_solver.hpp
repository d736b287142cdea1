#pragma once

#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/pose2.hpp"

namespace mosaicloc::tracking {

/// A point of the camera floor frame C matched to a point of the world, both mm.
struct Correspondence {
  Eigen::Vector2d camera_mm = Eigen::Vector2d::Zero();
  Eigen::Vector2d world_mm = Eigen::Vector2d::Zero();
  /// Standard deviation of world_mm along each axis, mm (used for the covariance, and to
  /// weight correspondences relative to each other).
  double sigma_mm = 0.01;
};

enum class RobustLoss { kNone, kHuber, kCauchy };
/// "none", "huber" or "cauchy", as the localizer configuration names them.
const char* ToString(RobustLoss loss);
inline constexpr RobustLoss kRobustLosses[] = {RobustLoss::kNone, RobustLoss::kHuber, RobustLoss::kCauchy};

/// How the pose is refined from the correspondences: the robust least-squares solve, or the
/// founding paper's iterated Kalman observer (Kelly, section 3: state (x, y, yaw), measurement
/// the world positions of the template centres z = h(x)).
enum class PoseMethod { kLeastSquares, kKalmanObserver };
/// "least-squares" or "kalman-observer", as the localizer configuration names them.
const char* ToString(PoseMethod method);
inline constexpr PoseMethod kPoseMethods[] = {PoseMethod::kLeastSquares, PoseMethod::kKalmanObserver};

struct PoseSolverOptions {
  PoseMethod method = PoseMethod::kLeastSquares;
  /// The Kalman observer's prior around the initial pose, one standard deviation: weak, so the
  /// pose it gives is the measurements' (the localizer's filter fuses it with the prediction,
  /// which must not count twice).
  double observer_prior_sigma_mm = 10.0;
  double observer_prior_sigma_deg = 5.0;
  double observer_prior_sigma_scale = 0.2;
  RobustLoss loss = RobustLoss::kCauchy;
  /// Scale of the robust loss, mm: residuals well below it count fully.
  double loss_scale_mm = 0.05;
  /// A correspondence whose residual exceeds this after the robust solve is an outlier; the
  /// pose is then solved again from the inliers alone.
  double outlier_threshold_mm = 0.15;
  int min_inliers = 3;
  int max_iterations = 50;  ///< reweighting rounds, and Levenberg-Marquardt steps in each
  /// false: skip the covariance, for a pose that only seeds a finer one;
  /// PoseSolution::covariance is then NaN.
  bool compute_covariance = true;
  /// Scale the covariance by the residuals' a-posteriori variance factor, sum (r_i / sigma_i)^2
  /// over the redundancy (2 inliers - parameters), where it exceeds 1: templates that agree
  /// less than their own sigmas promise (a view that differs from the map by more than noise:
  /// relief, changed floor) make a less certain fix.
  bool posterior_variance = false;
  /// Also estimate the image scale k (camera_mm is k times the true offset of a point from
  /// the camera: the camera is k times as high over the floor as calibrated) where four or
  /// more inliers determine it; the pose is then a similarity fit, its covariance marginal.
  bool estimate_scale = true;
  /// Also estimate the camera's tilt against the floor (with the scale) where at least
  /// `min_tilt_points` distinct template positions determine it: the correspondences are then
  /// rays of a pinhole `camera_height_mm` over the floor (camera_mm is a point's offset at
  /// that height), cast onto a plane the camera sees tilted, a homography of the ground plane.
  bool estimate_tilt = false;
  int min_tilt_points = 8;
  /// The tilt held where it is not estimated (too few points, or estimate_tilt off; rad, as
  /// PoseSolution's), from a prediction, and that prediction's standard deviation: the pose
  /// is solved through the pinhole tilted so, and its covariance carries what the tilt's
  /// uncertainty moves it by (a Schmidt "consider" parameter). All zero: a level camera, as
  /// sure as the calibration.
  double held_tilt_x_rad = 0.0;
  double held_tilt_y_rad = 0.0;
  double held_tilt_sigma_rad = 0.0;
  /// The height over the floor at which camera_mm is expressed (the calibrated height, times
  /// the scale the tracker renders at), mm; its focal length in pixels is this over mm per px.
  double camera_height_mm = 200.0;
  bool Check(std::string* why) const;
};

enum class PoseFailure { kNone, kTooFewInliers, kNotConverged };
const char* ToString(PoseFailure failure);

struct PoseSolution {
  PoseFailure failure = PoseFailure::kNone;
  bool ok() const { return failure == PoseFailure::kNone; }
  core::Pose2 world_from_camera;
  /// Covariance of (x_mm, y_mm, yaw_rad) of world_from_camera (NaN when not asked for).
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  std::vector<bool> inlier;       ///< per correspondence
  std::vector<double> residual_mm;  ///< per correspondence, at the solution
  /// The a-posteriori variance factor the covariance was scaled by (1 when not, or below 1).
  double variance_factor = 1.0;
  int inliers = 0;
  int iterations = 0;
  double rms_residual_mm = 0.0;   ///< over inliers
  /// The image scale k (1 when not estimated) and its standard deviation (infinite then).
  double scale = 1.0;
  double scale_sigma = std::numeric_limits<double>::infinity();
  bool scale_estimated = false;
  /// The camera's tilt against the floor, rad: the floor's normal in camera axes is
  /// (-tan tilt_y, tan tilt_x, 1) normalized (0 and an infinite sigma when not estimated);
  /// tilt_sigma_rad is the larger of the two standard deviations.
  double tilt_x_rad = 0.0;
  double tilt_y_rad = 0.0;
  double tilt_sigma_rad = std::numeric_limits<double>::infinity();
  bool tilt_estimated = false;
};

/// Planar pose of the camera from correspondences: the robust cost minimised by reweighted
/// Levenberg-Marquardt rounds of ceres::TinySolver with analytic Jacobians, an outlier pass,
/// and the covariance (J^T J)^-1 of the solution, with the loss's correction as
/// ceres::Covariance applies it. Needs two correspondences at
/// distinct points for a pose: one (or several at one point) fixes the translation only, and
/// the covariance's yaw variance is then infinite. Never throws for bad data.
PoseSolution SolvePlanarPose(const std::vector<Correspondence>& correspondences, const core::Pose2& initial,
                             const PoseSolverOptions& options);

/// The founding paper's pose observer: an iterated extended Kalman filter update (Gauss-Newton
/// iterations of the measurement update about the latest estimate, Bell and Cathey 1993) of the
/// state (x, y, yaw) (with the image scale k where options.estimate_scale and four distinct
/// points allow) from the prior `initial` (options.observer_prior_*) and the measurements
/// z_i = k R(yaw) camera_i + t with covariance sigma_i^2 I. Outliers by data snooping: the
/// correspondence with the largest residual beyond options.outlier_threshold_mm is dropped and
/// the update run again, one at a time. The covariance is the posterior's. No robust loss, no
/// tilt (options.estimate_tilt is refused by Check). Never throws for bad data.
/// SolvePlanarPose calls it when options.method is kKalmanObserver.
PoseSolution ObservePlanarPose(const std::vector<Correspondence>& correspondences, const core::Pose2& initial,
                               const PoseSolverOptions& options);

/// The residual of one correspondence and its Jacobian with respect to (x, y, yaw); exposed
/// for the Jacobian test. residual = R(yaw) camera + t - world, mm, divided by `scale`.
void PlanarResidual(const double* pose, const Correspondence& c, double scale, double* residual,
                    double* jacobian_row_major);
/// The same with the image scale k as a fourth parameter, pose = (x, y, yaw, k):
/// residual = k R(yaw) camera + t - world; the Jacobian is 2 x 4, row-major.
void SimilarityResidual(const double* pose, const Correspondence& c, double scale, double* residual,
                        double* jacobian_row_major);
/// The same through a tilted pinhole, pose = (x, y, yaw, k, a, b): the camera k h over a plane
/// whose normal in camera axes is (-b, a, 1) normalized; camera_mm is the ray through
/// (p_x / h, p_y / h, -1); the residual is t + R(yaw) q - w, q the ray's floor point less the
/// image centre's in the plane's frame (its x axis the camera's x projected onto the plane).
/// With a = b = 0 it is SimilarityResidual. The Jacobian is 2 x 6, row-major.
void TiltResidual(const double* pose, const Correspondence& c, double scale, double height_mm, double* residual,
                  double* jacobian_row_major);

}  // namespace mosaicloc::tracking
