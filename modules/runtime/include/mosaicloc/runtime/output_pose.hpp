#pragma once

#include <chrono>
#include <deque>

#include <Eigen/Core>

#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/core/timestamp.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/estimation/odometry.hpp"
#include "mosaicloc/estimation/pose_filter.hpp"

namespace mosaicloc::runtime {

/// The pose written to the PLC at the instant of the write (design.md section 6). The tracking
/// thread publishes the filter's latest state; the PLC thread may write long after it (a frame
/// that took long, a starved CPU), while it has read newer encoder samples itself. The state is
/// carried on along those samples' wheel travel, turned into motion with the calibration errors
/// the filter learnt, and only the short rest after the newest sample is extrapolated, at the
/// newest samples' velocity (their travel over the last `velocity_window`: a single sample
/// interval is the difference of two time stamps each a few ms uncertain). Extrapolating the
/// published state at its own velocity instead puts the vehicle where it would be had it not
/// braked, turned or sped up since.
/// Counters read unchanged two counter periods after their last change say the vehicle has
/// stopped (or its PLC stalled): the extrapolation then goes no further than the vehicle would
/// have gone braking to a stop at `braking_mps2` from the speed it had. Extrapolated on at that
/// speed, a vehicle that stopped from a creep was written 6 mm past its stop until the
/// counters were passed on as standing still (half a second after a change seen as moving).
/// One object per PLC thread: not thread safe.
class OutputPose {
 public:
  /// Throws core::Error (invalid input) when the odometry options fail Check().
  explicit OutputPose(const estimation::OdometryOptions& odometry,
                      core::Duration velocity_window = std::chrono::milliseconds(40),
                      core::Duration history = std::chrono::seconds(2),
                      core::Duration counter_period = std::chrono::milliseconds(10), double braking_mps2 = 3.0);

  /// An encoder sample as the localizer gets it (the same time stamp). A sample the odometry
  /// refuses (time not increasing, a counter glitch) is left out, as the localizer leaves it.
  void Add(const dataset::EncoderSample& sample);
  /// A read of the counters at `time` (its middle), whatever the stamper made of it: counters
  /// equal to the newest sample's, read more than two counter periods after it, bound the
  /// extrapolation.
  void Read(core::Timestamp time, const core::EncoderCounts& counts);
  /// Odometry became invalid: the counters and the travel seen so far are dropped.
  void Forget();

  struct Prediction {
    core::Pose2 world_from_vehicle;
    /// How long after the state's time the encoders carried it, and how long it was then
    /// extrapolated (after the newest sample, or from the state itself when no sample is newer).
    core::Duration carried{};
    core::Duration extrapolated{};
  };
  /// The published `state` (with the filter's calibration errors `wheel_scale`) moved on to
  /// `now`.
  Prediction At(const estimation::MotionState& state, const Eigen::Vector2d& wheel_scale, core::Timestamp now) const;

 private:
  struct Step {
    core::Timestamp end;
    core::Duration dt{};
    estimation::WheelTravel travel;
  };
  Eigen::Vector3d Velocity(const Eigen::Vector2d& wheel_scale) const;  // (forward, lateral, yaw) per second
  double StopSeconds(const Eigen::Vector3d& twist) const;  // how long on at `twist` covers its braking distance

  estimation::WheelOdometry odometry_;
  core::Duration velocity_window_;
  core::Duration history_;
  core::Duration counter_period_;
  double braking_mm_per_s2_;
  std::deque<Step> steps_;
  core::EncoderCounts newest_counts_;  // of the newest sample
  bool stopped_ = false;               // counters read unchanged two counter periods after it
};

}  // namespace mosaicloc::runtime
