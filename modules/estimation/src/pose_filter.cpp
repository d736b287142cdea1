#include "mosaicloc/estimation/pose_filter.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/LU>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::estimation {
namespace {

// Part `fraction` of an arc of constant curvature, and its share of the covariance (the
// wheel error model's variance grows linearly with travel).
core::Pose2 ArcPart(const core::Pose2& increment, double fraction) {
  return core::Pose2::Exp(fraction * increment.Log());
}

// d (x, y) / d (vx, vy, t) of the translation of Exp(vx, vy, t): (x, y) = V(t) (vx, vy),
// V = [[a, -c], [c, a]], a = sin(t)/t, c = (1 - cos t)/t (series near t = 0, where the closed
// forms cancel).
Eigen::Matrix<double, 2, 3> ExpTranslationJacobian(const Eigen::Vector3d& twist) {
  const double vx = twist.x(), vy = twist.y(), t = twist.z();
  double a, c, da, dc;  // sin(t)/t, (1 - cos t)/t and their derivatives in t
  if (std::abs(t) < 1e-4) {
    a = 1.0 - t * t / 6.0;
    c = 0.5 * t - t * t * t / 24.0;
    da = -t / 3.0;
    dc = 0.5 - t * t / 8.0;
  } else {
    const double sin_t = std::sin(t), cos_t = std::cos(t);
    a = sin_t / t;
    c = (1.0 - cos_t) / t;
    da = (t * cos_t - sin_t) / (t * t);
    dc = (t * sin_t - (1.0 - cos_t)) / (t * t);
  }
  Eigen::Matrix<double, 2, 3> j;
  j << a, -c, da * vx - dc * vy, c, a, dc * vx + da * vy;
  return j;
}

}  // namespace

bool PoseFilterOptions::Check(std::string* why) const {
  auto fail = [why](const char* message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (!(gate_chi2 > 0.0)) return fail("gate_chi2 must be > 0");
  if (history <= core::Duration::zero()) return fail("history must be > 0");
  if (!(extrapolation_position_variance_mm2_per_s >= 0.0) || !(extrapolation_yaw_variance_rad2_per_s >= 0.0)) {
    return fail("extrapolation variances must be >= 0");
  }
  if (!(coast_acceleration_mps2 >= 0.0) || !(coast_yaw_acceleration_radps2 >= 0.0)) {
    return fail("coast accelerations must be >= 0");
  }
  if (!(wheel_scale_sigma >= 0.0 && wheel_scale_sigma <= 0.5)) return fail("wheel_scale_sigma must be in [0, 0.5]");
  if (!(wheel_scale_walk_per_sqrt_m >= 0.0 && wheel_scale_walk_per_sqrt_m <= 0.1)) {
    return fail("wheel_scale_walk_per_sqrt_m must be in [0, 0.1]");
  }
  if (!(steering_offset_sigma_deg >= 0.0 && steering_offset_sigma_deg <= 20.0)) {
    return fail("steering_offset_sigma_deg must be in [0, 20]");
  }
  if (!(steering_offset_walk_deg_per_sqrt_m >= 0.0 && steering_offset_walk_deg_per_sqrt_m <= 1.0)) {
    return fail("steering_offset_walk_deg_per_sqrt_m must be in [0, 1]");
  }
  if (!(lateral_scale_sigma >= 0.0 && lateral_scale_sigma <= 0.5)) return fail("lateral_scale_sigma must be in [0, 0.5]");
  return true;
}

Eigen::Vector2d PoseFilter::CalibrationSigma() const {
  if (options_.kind == core::DriveKind::kTricycle) {
    return {options_.wheel_scale_sigma, options_.steering_offset_sigma_deg * std::numbers::pi / 180.0};
  }
  if (options_.kind == core::DriveKind::kMecanum) return {options_.wheel_scale_sigma, options_.lateral_scale_sigma};
  return Eigen::Vector2d::Constant(options_.wheel_scale_sigma);
}

Eigen::Vector2d PoseFilter::CalibrationWalk() const {
  if (options_.kind == core::DriveKind::kTricycle) {
    return {options_.wheel_scale_walk_per_sqrt_m, options_.steering_offset_walk_deg_per_sqrt_m * std::numbers::pi / 180.0};
  }
  return Eigen::Vector2d::Constant(options_.wheel_scale_walk_per_sqrt_m);
}

PoseFilter::PoseFilter(const PoseFilterOptions& options, core::Timestamp time, const core::Pose2& world_from_vehicle,
                       const Eigen::Matrix3d& covariance)
    : options_(options) {
  std::string why;
  if (!options_.Check(&why)) core::ThrowInvalidInput("pose filter options: " + why);
  Node start;
  const Eigen::Vector2d sigma = CalibrationSigma();
  start.covariance.bottomRightCorner<2, 2>() = sigma.cwiseProduct(sigma).asDiagonal();
  history_.push_back(start);
  Reset(time, world_from_vehicle, covariance);
}

void PoseFilter::Reset(core::Timestamp time, const core::Pose2& world_from_vehicle, const Eigen::Matrix3d& covariance) {
  Node node;
  node.time = time;
  node.world_from_vehicle = world_from_vehicle;
  node.wheel_scale = history_.back().wheel_scale;
  node.covariance.topLeftCorner<3, 3>() = covariance;
  node.covariance.bottomRightCorner<2, 2>() = history_.back().covariance.bottomRightCorner<2, 2>();
  history_.clear();
  history_.push_back(node);
  last_odometry_ = time;
}

void PoseFilter::Propagate(const Node& from, Node* to) const {
  const double yaw = from.world_from_vehicle.yaw_rad();
  const double c = std::cos(yaw), s = std::sin(yaw);
  const Eigen::Matrix2d rotation = from.world_from_vehicle.Rotation();
  Matrix5d f = Matrix5d::Identity();
  Matrix5d noise = Matrix5d::Zero();
  to->wheel_scale = from.wheel_scale;
  if (to->travel.measured()) {
    // d(pose+)/dc through (dx, dy, dtheta).
    Eigen::Matrix<double, 3, 2> d_motion;  // columns c; rows dx, dy, dtheta
    const Eigen::Vector3d motion = to->travel.Motion(from.wheel_scale, &d_motion);
    to->increment = core::Pose2::Exp(motion);
    f.block<2, 2>(0, 3) = rotation * ExpTranslationJacobian(motion) * d_motion;
    f.block<1, 2>(2, 3) = d_motion.row(2);
    const Eigen::Vector2d walk = CalibrationWalk();
    const Eigen::Vector2d rolled_m = to->travel.Rolled() * 1e-3;
    noise(3, 3) = walk.x() * walk.x() * rolled_m.x();
    noise(4, 4) = walk.y() * walk.y() * rolled_m.y();
  }
  const double dx = to->increment.x_mm(), dy = to->increment.y_mm();
  f(0, 2) = -(s * dx + c * dy);
  f(1, 2) = c * dx - s * dy;
  Eigen::Matrix3d g = Eigen::Matrix3d::Identity();
  g.topLeftCorner<2, 2>() = rotation;
  noise.topLeftCorner<3, 3>() = g * to->increment_covariance * g.transpose();
  to->world_from_vehicle = from.world_from_vehicle * to->increment;
  to->covariance = f * from.covariance * f.transpose() + noise;
}

PoseFilter::Node PoseFilter::Part(const Node& node, double fraction) {
  Node part = node;
  if (node.travel.measured()) {
    part.travel = node.travel.Part(fraction);
  } else {
    part.increment = ArcPart(node.increment, fraction);
  }
  part.increment_covariance = fraction * node.increment_covariance;
  return part;
}

void PoseFilter::Predict(core::Timestamp time, const OdometryIncrement& increment) {
  if (time <= history_.back().time) return;  // out of order: odometry never goes back
  Node node;
  node.time = time;
  node.travel = increment.travel;
  node.increment = increment.previous_from_current;
  node.increment_covariance = increment.covariance;
  // The state may already be past the increment's start (the filter coasted to a frame while
  // the odometry was late): only the part of the arc after it is new motion.
  const core::Timestamp start = time - increment.dt;
  if (increment.dt > core::Duration::zero() && start < history_.back().time) {
    const double done = core::ToSeconds(history_.back().time - start) / core::ToSeconds(increment.dt);
    node = Part(node, 1.0 - done);
    node.time = time;
  }
  Propagate(history_.back(), &node);
  history_.push_back(node);
  last_odometry_ = time;
  const double dt_s = core::ToSeconds(increment.dt);
  if (dt_s > 0.0) {
    // The speeds of the whole increments over the speed window, with the wheels' scales applied.
    Eigen::Vector3d twist = increment.previous_from_current.Log();
    if (increment.travel.measured()) twist = increment.travel.Motion(node.wheel_scale);
    recent_.push_back({time, increment.dt, twist});
    while (recent_.size() > 1 && time - (recent_.front().end - recent_.front().dt) > options_.speed_window) {
      recent_.pop_front();
    }
    Eigen::Vector3d motion = Eigen::Vector3d::Zero();
    core::Duration span{};
    for (const Recent& r : recent_) {
      motion += r.motion;
      span += r.dt;
    }
    const Eigen::Vector3d speed = motion / core::ToSeconds(span);
    forward_speed_mm_per_s_ = speed.x();
    lateral_speed_mm_per_s_ = speed.y();
    yaw_rate_rad_per_s_ = speed.z();
  }
  Prune();
}

void PoseFilter::Coast(core::Timestamp time) {
  if (time <= history_.back().time) return;
  const double dt_s = core::ToSeconds(time - history_.back().time);
  // Unknown acceleration since the last odometry: the variance a^2 T^4 / 4 at T seconds,
  // added step by step (the steps telescope to it).
  const double t_old = core::ToSeconds(history_.back().time - last_odometry_);
  const double t_new = core::ToSeconds(time - last_odometry_);
  const double quartic = std::pow(t_new, 4) - std::pow(t_old, 4);
  const double a_mm = options_.coast_acceleration_mps2 * 1e3;
  const double position = options_.extrapolation_position_variance_mm2_per_s * dt_s + 0.25 * a_mm * a_mm * quartic;
  const double yaw = options_.extrapolation_yaw_variance_rad2_per_s * dt_s +
                     0.25 * std::pow(options_.coast_yaw_acceleration_radps2, 2) * quartic;
  Node node;
  node.time = time;
  node.increment = core::Pose2::Exp(Eigen::Vector3d(forward_speed_mm_per_s_, lateral_speed_mm_per_s_, yaw_rate_rad_per_s_) * dt_s);
  node.increment_covariance = Eigen::Vector3d(position, position, yaw).asDiagonal();
  Propagate(history_.back(), &node);
  history_.push_back(node);
  Prune();
}

MotionState PoseFilter::Latest() const {
  const Node& node = history_.back();
  return {node.time,          node.world_from_vehicle,  node.covariance.topLeftCorner<3, 3>(), forward_speed_mm_per_s_,
          yaw_rate_rad_per_s_, lateral_speed_mm_per_s_};
}

Eigen::Vector3d MotionState::Twist() const {
  return {forward_speed_mm_per_s, lateral_speed_mm_per_s, yaw_rate_rad_per_s};
}

core::Pose2 MotionState::PoseAt(core::Timestamp at) const {
  return world_from_vehicle * core::Pose2::Exp(core::ToSeconds(at - time) * Twist());
}

void PoseFilter::Prune() {
  const core::Timestamp oldest = history_.back().time - options_.history;
  while (history_.size() > 2 && history_[1].time <= oldest) history_.pop_front();
}

std::size_t PoseFilter::NodeBefore(core::Timestamp time) const {
  const auto after = std::upper_bound(history_.begin(), history_.end(), time,
                                      [](core::Timestamp t, const Node& n) { return t < n.time; });
  return after == history_.begin() ? 0 : static_cast<std::size_t>(after - history_.begin()) - 1;
}

core::Pose2 PoseFilter::PoseAt(core::Timestamp time) const {
  const std::size_t k = NodeBefore(time);
  const Node& node = history_[k];
  if (k + 1 < history_.size()) {
    const Node& next = history_[k + 1];
    const double fraction = core::ToSeconds(time - node.time) / core::ToSeconds(next.time - node.time);
    return node.world_from_vehicle * ArcPart(next.increment, std::clamp(fraction, 0.0, 1.0));
  }
  const double dt_s = core::ToSeconds(time - node.time);
  if (dt_s <= 0.0) return node.world_from_vehicle;
  return node.world_from_vehicle *
         core::Pose2::Exp(Eigen::Vector3d(forward_speed_mm_per_s_, lateral_speed_mm_per_s_, yaw_rate_rad_per_s_) * dt_s);
}

Eigen::Matrix3d PoseFilter::CovarianceAt(core::Timestamp time) const {
  const std::size_t k = NodeBefore(time);
  const Node& node = history_[k];
  if (k + 1 < history_.size()) {
    const Node& next = history_[k + 1];
    const double fraction =
        std::clamp(core::ToSeconds(time - node.time) / core::ToSeconds(next.time - node.time), 0.0, 1.0);
    return (1.0 - fraction) * node.covariance.topLeftCorner<3, 3>() + fraction * next.covariance.topLeftCorner<3, 3>();
  }
  const double dt_s = std::max(0.0, core::ToSeconds(time - node.time));
  Eigen::Matrix3d p = node.covariance.topLeftCorner<3, 3>();
  p(0, 0) += options_.extrapolation_position_variance_mm2_per_s * dt_s;
  p(1, 1) += options_.extrapolation_position_variance_mm2_per_s * dt_s;
  p(2, 2) += options_.extrapolation_yaw_variance_rad2_per_s * dt_s;
  return p;
}

FixOutcome PoseFilter::Correct(core::Timestamp time, const core::Pose2& world_from_vehicle,
                               const Eigen::Matrix3d& covariance, const Eigen::Matrix3d& prediction_spread) {
  FixOutcome outcome;
  if (time > history_.back().time) {
    outcome.reason = "fix is newer than the latest odometry";
    return outcome;
  }
  if (time < history_.front().time) {
    outcome.reason = "fix is older than the filter's history";
    return outcome;
  }
  Split split = SplitAt(time);
  Node& at = split.at;
  at.covariance.topLeftCorner<3, 3>() += prediction_spread;

  const Eigen::Vector3d residual(world_from_vehicle.x_mm() - at.world_from_vehicle.x_mm(),
                                 world_from_vehicle.y_mm() - at.world_from_vehicle.y_mm(),
                                 core::WrapAngle(world_from_vehicle.yaw_rad() - at.world_from_vehicle.yaw_rad()));
  const Eigen::Matrix3d s = at.covariance.topLeftCorner<3, 3>() + covariance;
  const Eigen::Matrix3d s_inverse = s.inverse();
  outcome.mahalanobis2 = residual.dot(s_inverse * residual);
  outcome.innovation = residual;
  outcome.innovation_covariance = s;
  if (!std::isfinite(outcome.mahalanobis2) || outcome.mahalanobis2 > options_.gate_chi2) {
    outcome.reason = "fix is " + std::to_string(std::sqrt(std::max(outcome.mahalanobis2, 0.0))) +
                     " sigma from the prediction (residual " + std::to_string(residual.x()) + " mm, " +
                     std::to_string(residual.y()) + " mm, " + std::to_string(residual.z()) + " rad; sigma " +
                     std::to_string(std::sqrt(s(0, 0))) + " mm, " + std::to_string(std::sqrt(s(1, 1))) + " mm, " +
                     std::to_string(std::sqrt(s(2, 2))) + " rad)";
    return outcome;
  }
  // H = [I 0]: P H^T is P's first three columns.
  const Eigen::Matrix<double, 5, 3> gain = at.covariance.leftCols<3>() * s_inverse;
  const Eigen::Matrix<double, 5, 1> correction = gain * residual;
  at.world_from_vehicle = core::Pose2(at.world_from_vehicle.x_mm() + correction(0),
                                      at.world_from_vehicle.y_mm() + correction(1),
                                      at.world_from_vehicle.yaw_rad() + correction(2));
  at.wheel_scale += correction.tail<2>();
  Matrix5d i_minus_kh = Matrix5d::Identity();
  i_minus_kh.leftCols<3>() -= gain;
  at.covariance = i_minus_kh * at.covariance * i_minus_kh.transpose() + gain * covariance * gain.transpose();
  at.covariance = 0.5 * (at.covariance + at.covariance.transpose());

  Replay(std::move(split));
  outcome.accepted = true;
  return outcome;
}

Eigen::Matrix3d PoseFilter::CorrectedCovariance(core::Timestamp time, const Eigen::Matrix3d& covariance,
                                                const Eigen::Matrix3d& prediction_spread) const {
  // (I - K) P at the gain K = P (P + R)^-1, which the Joseph form of Correct reduces to.
  const Eigen::Matrix3d predicted = CovarianceAt(time) + prediction_spread;
  const Eigen::Matrix3d corrected = predicted * (predicted + covariance).ldlt().solve(covariance);
  return 0.5 * (corrected + corrected.transpose());
}

PoseFilter::Split PoseFilter::SplitAt(core::Timestamp time) const {
  // The state at `time`: split the increment that spans it.
  Split split;
  split.k = NodeBefore(time);
  split.at = history_[split.k];
  split.later.assign(history_.begin() + static_cast<std::ptrdiff_t>(split.k) + 1, history_.end());
  split.split = time > split.at.time && !split.later.empty();  // else `time` falls on node k
  if (split.split) {
    const Node& next = split.later.front();
    const double fraction = core::ToSeconds(time - split.at.time) / core::ToSeconds(next.time - split.at.time);
    Node part = Part(next, fraction);
    part.time = time;
    Propagate(split.at, &part);
    const core::Timestamp next_time = next.time;
    split.later.front() = Part(next, 1.0 - fraction);
    split.later.front().time = next_time;
    split.at = part;
  }
  return split;
}

void PoseFilter::Replay(Split split) {
  // The later odometry, replayed on the new state at the split.
  history_.erase(history_.begin() + static_cast<std::ptrdiff_t>(split.k + (split.split ? 1 : 0)), history_.end());
  history_.push_back(split.at);
  for (Node& node : split.later) {
    Propagate(history_.back(), &node);
    history_.push_back(node);
  }
}

void PoseFilter::RestartAt(core::Timestamp time, const core::Pose2& world_from_vehicle,
                           const Eigen::Matrix3d& covariance) {
  if (time >= history_.back().time || time < history_.front().time) {
    // After the history (the state coasts to it) or before it: nothing to keep.
    const core::Timestamp odometry = last_odometry_;
    Reset(time, world_from_vehicle, covariance);
    if (time < odometry) last_odometry_ = odometry;
    return;
  }
  Split split = SplitAt(time);
  split.at.world_from_vehicle = world_from_vehicle;
  // The new pose is independent of the old one, and so of how the scales were estimated.
  const Eigen::Matrix2d scale_covariance = split.at.covariance.bottomRightCorner<2, 2>();
  split.at.covariance.setZero();
  split.at.covariance.topLeftCorner<3, 3>() = covariance;
  split.at.covariance.bottomRightCorner<2, 2>() = scale_covariance;
  // The history before `time` held the old, wrong states: drop it.
  Replay(std::move(split));
  while (history_.size() > 1 && history_.front().time < time) history_.pop_front();
}

}  // namespace mosaicloc::estimation
