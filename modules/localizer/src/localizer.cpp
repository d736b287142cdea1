#include "mosaicloc/localizer/localizer.hpp"

#include <algorithm>
#include <cmath>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::localizer {
namespace {

// d(a * b)/d(a) for SE2 poses (x, y, yaw), b fixed: the lever arm of b's translation turns
// with a's yaw.
Eigen::Matrix3d ComposeJacobian(const core::Pose2& a, const core::Pose2& b) {
  const double c = std::cos(a.yaw_rad()), s = std::sin(a.yaw_rad());
  Eigen::Matrix3d j = Eigen::Matrix3d::Identity();
  j(0, 2) = -s * b.x_mm() - c * b.y_mm();
  j(1, 2) = c * b.x_mm() - s * b.y_mm();
  return j;
}

}  // namespace

bool LocalizerOptions::Check(std::string* why) const {
  if (!tracker.Check(why) || !filter.Check(why) || !lock.Check(why) || !odometry.Check(why)) return false;
  auto fail = [why](const char* message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (!(fix_sigma_floor_mm >= 0.0) || !(fix_sigma_floor_rad >= 0.0)) return fail("fix sigma floors must be >= 0");
  if (!(fix_covariance_scale >= 1.0)) return fail("fix_covariance_scale must be >= 1");
  return true;
}

Eigen::Matrix3d CameraCovariance(const core::Pose2& world_from_vehicle, const core::Pose2& vehicle_from_camera,
                                 const Eigen::Matrix3d& vehicle_covariance) {
  const Eigen::Matrix3d j = ComposeJacobian(world_from_vehicle, vehicle_from_camera);
  return j * vehicle_covariance * j.transpose();
}

Eigen::Matrix3d VehicleCovariance(const core::Pose2& world_from_camera, const core::Pose2& vehicle_from_camera,
                                  const Eigen::Matrix3d& camera_covariance) {
  const Eigen::Matrix3d j = ComposeJacobian(world_from_camera, vehicle_from_camera.Inverse());
  return j * camera_covariance * j.transpose();
}

Localizer::Localizer(const camera::IdealCamera& camera, const LocalizerOptions& options,
                     const tracking::ReferenceRaster& reference)
    : camera_(camera),
      options_(options),
      reference_(reference),
      tracker_(camera, options.tracker),
      odometry_(options.odometry),
      lock_(options.lock) {
  std::string why;
  if (!options_.Check(&why)) core::ThrowInvalidInput("localizer options: " + why);
}

void Localizer::Initialize(core::Timestamp time, const core::Pose2& world_from_vehicle,
                           const Eigen::Matrix3d& covariance) {
  filter_.emplace(options_.filter, time, world_from_vehicle, covariance);
}

bool Localizer::AddEncoders(core::Timestamp time, std::int32_t left_ticks, std::int32_t right_ticks) {
  const auto increment = odometry_.Update(time, left_ticks, right_ticks);
  if (!increment) return false;
  if (filter_ && increment.value().dt > core::Duration::zero()) filter_->Predict(time, increment.value());
  return true;
}

core::Pose2 Localizer::PoseAt(core::Timestamp time) const {
  return filter_ ? filter_->PoseAt(time) : core::Pose2::Identity();
}

Eigen::Matrix3d Localizer::CovarianceAt(core::Timestamp time) const {
  return filter_ ? filter_->CovarianceAt(time) : Eigen::Matrix3d::Identity() * 1e12;
}

FrameOutcome Localizer::ProcessFrame(core::Timestamp time, const cv::Mat& frame) {
  FrameOutcome outcome;
  if (!filter_) core::ThrowRuntime("localizer: ProcessFrame before Initialize");
  const core::Pose2 predicted = filter_->PoseAt(time);
  const Eigen::Matrix3d predicted_covariance = filter_->CovarianceAt(time);
  const core::Pose2 prior_camera = predicted * options_.vehicle_from_camera;
  const Eigen::Matrix3d prior_camera_covariance =
      CameraCovariance(predicted, options_.vehicle_from_camera, predicted_covariance);

  outcome.track = tracker_.Track(frame, prior_camera, prior_camera_covariance, reference_);
  if (outcome.track.ok()) {
    const core::Pose2 fix = outcome.track.world_from_camera * options_.vehicle_from_camera.Inverse();
    Eigen::Matrix3d fix_covariance = options_.fix_covariance_scale *
                                     VehicleCovariance(outcome.track.world_from_camera, options_.vehicle_from_camera,
                                                       outcome.track.covariance);
    fix_covariance(0, 0) += options_.fix_sigma_floor_mm * options_.fix_sigma_floor_mm;
    fix_covariance(1, 1) += options_.fix_sigma_floor_mm * options_.fix_sigma_floor_mm;
    fix_covariance(2, 2) += options_.fix_sigma_floor_rad * options_.fix_sigma_floor_rad;
    outcome.fix_world_from_vehicle = fix;
    outcome.fix_quality = std::clamp(outcome.track.mean_zncc, 0.0, 1.0);
    const estimation::FixOutcome applied = filter_->Correct(time, fix, fix_covariance);
    outcome.fixed = applied.accepted;
    if (!applied.accepted) outcome.reason = "fix rejected: " + applied.reason;
  } else {
    outcome.reason = tracking::ToString(outcome.track.failure) + std::string(": ") + outcome.track.reason;
  }
  outcome.world_from_vehicle = filter_->PoseAt(time);
  outcome.covariance = filter_->CovarianceAt(time);
  const double sigma_mm = std::sqrt(std::max(outcome.covariance(0, 0), outcome.covariance(1, 1)));
  outcome.lock = lock_.Update(outcome.fixed, sigma_mm, outcome.reason);
  return outcome;
}

}  // namespace mosaicloc::localizer
