#include "mosaicloc/runtime/output_pose.hpp"

#include <algorithm>

namespace mosaicloc::runtime {

OutputPose::OutputPose(const estimation::OdometryOptions& odometry, core::Duration velocity_window,
                       core::Duration history, core::Duration counter_period, double braking_mps2)
    : odometry_(odometry),
      velocity_window_(velocity_window),
      history_(history),
      counter_period_(counter_period),
      braking_mm_per_s2_(braking_mps2 * 1e3) {}

void OutputPose::Add(const dataset::EncoderSample& sample) {
  const auto increment = odometry_.Update(sample.time, sample.counts);
  if (!increment.ok() || increment.value().dt <= core::Duration::zero()) return;
  steps_.push_back({sample.time, increment.value().dt, increment.value().travel});
  while (steps_.size() > 1 && steps_.front().end < sample.time - history_) steps_.pop_front();
  newest_counts_ = sample.counts;
  stopped_ = false;
}

void OutputPose::Read(core::Timestamp time, const core::EncoderCounts& counts) {
  // Two periods: a read just after the next update's instant may not see it yet.
  if (counter_period_ > core::Duration::zero() && !steps_.empty() && counts == newest_counts_ &&
      time - steps_.back().end > 2 * counter_period_) {
    stopped_ = true;
  }
}

void OutputPose::Forget() {
  odometry_.ForgetCounters();
  steps_.clear();
  stopped_ = false;
}

double OutputPose::StopSeconds(const Eigen::Vector3d& twist) const {
  // Braking from speed v covers v^2 / 2a: the distance of v / 2a seconds at v.
  return twist.head<2>().norm() / (2.0 * braking_mm_per_s2_);
}

Eigen::Vector3d OutputPose::Velocity(const Eigen::Vector2d& wheel_scale) const {
  // The travel over the last velocity_window_ (at least the newest step) over its span: one
  // step's span is the difference of two time stamps each a few ms uncertain, so its speed
  // alone can be a fifth off.
  Eigen::Vector3d travelled = Eigen::Vector3d::Zero();
  core::Timestamp since = steps_.back().end;
  for (auto step = steps_.rbegin(); step != steps_.rend(); ++step) {
    if (step != steps_.rbegin() && steps_.back().end - (step->end - step->dt) > velocity_window_) break;
    travelled += step->travel.Motion(wheel_scale);
    since = step->end - step->dt;
  }
  return travelled / core::ToSeconds(steps_.back().end - since);
}

OutputPose::Prediction OutputPose::At(const estimation::MotionState& state, const Eigen::Vector2d& wheel_scale,
                                      core::Timestamp now) const {
  Prediction out;
  // The steps that end after the state: the travel the filter has not seen.
  const auto first = std::upper_bound(steps_.begin(), steps_.end(), state.time,
                                      [](core::Timestamp t, const Step& s) { return t < s.end; });
  if (first == steps_.end()) {
    // The filter is as new as the counters: on from it at the counters' velocity, the newest
    // this thread has.
    const Eigen::Vector3d twist = steps_.empty() ? state.Twist() : Velocity(wheel_scale);
    double seconds = core::ToSeconds(now - state.time);
    if (stopped_) seconds = std::min(seconds, StopSeconds(twist));
    out.world_from_vehicle = state.world_from_vehicle * core::Pose2::Exp(seconds * twist);
    out.extrapolated = now - state.time;
    return out;
  }
  core::Pose2 pose = state.world_from_vehicle;
  core::Timestamp at = state.time;
  // The first step's start before the state: odometry has no sample in between (the state
  // came from a frame after the PLC thread's newest sample, or from before a re-seed), so that
  // span moves at the state's own velocity.
  const core::Timestamp start = first->end - first->dt;
  if (start > at) {
    pose = pose * core::Pose2::Exp(core::ToSeconds(start - at) * state.Twist());
    at = start;
  }
  for (auto step = first; step != steps_.end(); ++step) {
    const double dt_s = core::ToSeconds(step->dt);
    // Only the part of the step after `at` is new (the state may lie inside the step).
    const double fraction = std::clamp(core::ToSeconds(step->end - at) / dt_s, 0.0, 1.0);
    pose = pose * core::Pose2::Exp(step->travel.Part(fraction).Motion(wheel_scale));
    at = step->end;
  }
  out.carried = at - state.time;
  if (now > at) {
    const Eigen::Vector3d twist = Velocity(wheel_scale);
    double seconds = core::ToSeconds(now - at);
    if (stopped_) seconds = std::min(seconds, StopSeconds(twist));
    pose = pose * core::Pose2::Exp(seconds * twist);
    out.extrapolated = now - at;
  }
  out.world_from_vehicle = pose;
  return out;
}

}  // namespace mosaicloc::runtime
