#include "mosaicloc/runtime/output_pose.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <vector>

#include <gtest/gtest.h>

namespace mosaicloc::runtime {
namespace {

using std::chrono::milliseconds;

constexpr double kTrackMm = 500.0;
constexpr double kRadiusMm = 75.0;
constexpr std::int64_t kTicks = 1 << 20;  // fine counters: the tests measure the carrying, not the rounding

estimation::OdometryOptions Differential() {
  estimation::OdometryOptions options;
  options.wheels.kind = core::DriveKind::kDifferential;
  options.wheels.left_wheel_radius_mm = kRadiusMm;
  options.wheels.right_wheel_radius_mm = kRadiusMm;
  options.wheels.track_width_mm = kTrackMm;
  options.wheels.ticks_per_revolution = kTicks;
  return options;
}

// A differential vehicle whose wheels roll (1 + k) times what its counters say: it drives at
// the speed and yaw rate asked for, and its counters and true pose follow.
class Vehicle {
 public:
  explicit Vehicle(Eigen::Vector2d k) : k_(k) {}
  // Drives `ms` milliseconds at v mm/s and w rad/s; returns the counters at the end.
  dataset::EncoderSample Drive(int ms, double v_mm_per_s, double w_rad_per_s) {
    const double dt = ms * 1e-3;
    const double left = (v_mm_per_s - w_rad_per_s * kTrackMm / 2.0) * dt;
    const double right = (v_mm_per_s + w_rad_per_s * kTrackMm / 2.0) * dt;
    left_ticks_ += left / (1.0 + k_.x()) / (2.0 * M_PI * kRadiusMm) * kTicks;
    right_ticks_ += right / (1.0 + k_.y()) / (2.0 * M_PI * kRadiusMm) * kTicks;
    pose_ = pose_ * core::Pose2::Exp(Eigen::Vector3d(v_mm_per_s * dt, 0.0, w_rad_per_s * dt));
    time_ = time_ + milliseconds(ms);
    dataset::EncoderSample sample;
    sample.time = time_;
    sample.counts.left_ticks = static_cast<std::int32_t>(std::lround(left_ticks_));
    sample.counts.right_ticks = static_cast<std::int32_t>(std::lround(right_ticks_));
    return sample;
  }
  // What the tracking thread publishes: the true pose now, moving at v and w.
  estimation::MotionState State(double v_mm_per_s, double w_rad_per_s) const {
    estimation::MotionState state;
    state.time = time_;
    state.world_from_vehicle = pose_;
    state.forward_speed_mm_per_s = v_mm_per_s;
    state.yaw_rate_rad_per_s = w_rad_per_s;
    return state;
  }
  const core::Pose2& pose() const { return pose_; }
  core::Timestamp time() const { return time_; }

 private:
  Eigen::Vector2d k_;
  double left_ticks_ = 0.0, right_ticks_ = 0.0;
  core::Pose2 pose_ = core::Pose2(1000.0, 2000.0, 0.3);
  core::Timestamp time_ = core::Timestamp() + std::chrono::seconds(5);
};


TEST(OutputPose, ABrakingVehicleIsCarriedOnByItsCountersNotByTheStatesOldSpeed) {
  const Eigen::Vector2d k(0.02, 0.025);
  Vehicle vehicle(k);
  OutputPose output(Differential());
  output.Add(vehicle.Drive(10, 1500.0, 0.0));
  // The tracking thread publishes at 1.5 m/s, then falls behind while the vehicle brakes at
  // 3 m/s^2 for 300 ms, its counters read every 10 ms.
  const estimation::MotionState state = vehicle.State(1500.0, 0.0);
  double v = 1500.0;
  for (int i = 0; i < 30; ++i) {
    v -= 30.0;
    output.Add(vehicle.Drive(10, v, 0.0));
  }
  const core::Timestamp now = vehicle.time() + milliseconds(4);
  const core::Pose2 truth = vehicle.pose() * core::Pose2::Exp(Eigen::Vector3d(v * 0.004, 0.0, 0.0));
  const OutputPose::Prediction carried = output.At(state, k, now);
  // The last 4 ms at the speed of the last 40 ms, which lags the braking by 20 ms (60 mm/s).
  EXPECT_LT(core::Distance(carried.world_from_vehicle, truth), 0.25);
  EXPECT_EQ(carried.carried, milliseconds(300));
  EXPECT_EQ(carried.extrapolated, milliseconds(4));
  // The state's own speed would have put it 135 mm ahead; the counters without the wheels'
  // learnt scales 2 % short of the 315 mm driven.
  EXPECT_GT(core::Distance(state.PoseAt(now), truth), 130.0);
  const double unscaled = core::Distance(output.At(state, Eigen::Vector2d::Zero(), now).world_from_vehicle, truth);
  EXPECT_GT(unscaled, 5.0);
  EXPECT_LT(unscaled, 8.0);
}

TEST(OutputPose, ABendIsFollowedAlongItsArcs) {
  const Eigen::Vector2d k(-0.01, 0.015);
  Vehicle vehicle(k);
  OutputPose output(Differential());
  output.Add(vehicle.Drive(10, 1000.0, 0.0));
  const estimation::MotionState state = vehicle.State(1000.0, 0.0);
  for (int i = 0; i < 20; ++i) output.Add(vehicle.Drive(10, 1000.0, 0.05 * i));  // steering into a bend
  const core::Pose2 truth = vehicle.pose();
  const core::Pose2 carried = output.At(state, k, vehicle.time()).world_from_vehicle;
  EXPECT_LT(core::Distance(carried, truth), 0.01);
  EXPECT_NEAR(carried.yaw_rad(), truth.yaw_rad(), 1e-5);
}

TEST(OutputPose, TheSpeedExtrapolatedIsTheLastFortyMillisecondsNotOneJitteredInterval) {
  // Counters read every 10 ms, each stamped up to 2.5 ms off: the vehicle at a constant 2 m/s.
  Vehicle vehicle(Eigen::Vector2d::Zero());
  OutputPose output(Differential());
  output.Add(vehicle.Drive(10, 2000.0, 0.0));
  const estimation::MotionState state = vehicle.State(2000.0, 0.0);
  const int jitter_ms[] = {2, -2, 1, -1, 2, -2, 2, -2, 2, -2};
  for (const int jitter : jitter_ms) {
    dataset::EncoderSample sample = vehicle.Drive(10, 2000.0, 0.0);
    sample.time = sample.time + milliseconds(jitter);
    output.Add(sample);
  }
  // The newest sample was stamped 2 ms early; 10 ms after its true time the vehicle is 20 mm on.
  const core::Timestamp now = vehicle.time() + milliseconds(10);
  const core::Pose2 truth = vehicle.pose() * core::Pose2::Exp(Eigen::Vector3d(20.0, 0.0, 0.0));
  // Its own interval (8 ms for 20 mm) says 2.5 m/s: 30 mm on, 6 mm too far (4 mm of it the
  // stamp's own error, which no velocity removes); the last 40 ms say 2 m/s.
  EXPECT_LT(core::Distance(output.At(state, Eigen::Vector2d::Zero(), now).world_from_vehicle, truth), 4.0 + 0.5);
  OutputPose one_interval(Differential(), milliseconds(1));
  Vehicle again(Eigen::Vector2d::Zero());
  one_interval.Add(again.Drive(10, 2000.0, 0.0));
  for (const int jitter : jitter_ms) {
    dataset::EncoderSample sample = again.Drive(10, 2000.0, 0.0);
    sample.time = sample.time + milliseconds(jitter);
    one_interval.Add(sample);
  }
  EXPECT_GT(core::Distance(one_interval.At(state, Eigen::Vector2d::Zero(), now).world_from_vehicle, truth), 5.5);
}

TEST(OutputPose, AStateInsideASampleIntervalTakesOnlyTheTravelAfterIt) {
  const Eigen::Vector2d k = Eigen::Vector2d::Zero();
  Vehicle vehicle(k);
  OutputPose output(Differential());
  output.Add(vehicle.Drive(10, 800.0, 0.2));
  // The tracking thread coasted to a frame 4 ms into the next 10 ms of constant motion.
  Vehicle at_frame = vehicle;
  at_frame.Drive(4, 800.0, 0.2);
  const estimation::MotionState state = at_frame.State(800.0, 0.2);
  output.Add(vehicle.Drive(10, 800.0, 0.2));
  output.Add(vehicle.Drive(10, 800.0, 0.2));
  const OutputPose::Prediction carried = output.At(state, k, vehicle.time());
  EXPECT_LT(core::Distance(carried.world_from_vehicle, vehicle.pose()), 0.01);
  EXPECT_NEAR(carried.world_from_vehicle.yaw_rad(), vehicle.pose().yaw_rad(), 1e-6);
  EXPECT_EQ(carried.carried, milliseconds(16));
}

TEST(OutputPose, WithoutNewerSamplesTheStateMovesAtTheCountersSpeedAndAfterForgetAtItsOwn) {
  Vehicle vehicle(Eigen::Vector2d::Zero());
  OutputPose output(Differential());
  output.Add(vehicle.Drive(10, 1000.0, 0.1));
  output.Add(vehicle.Drive(10, 1000.0, 0.1));
  const estimation::MotionState state = vehicle.State(900.0, 0.1);  // newer than every sample
  const core::Timestamp now = state.time + milliseconds(20);
  const OutputPose::Prediction latest = output.At(state, Eigen::Vector2d::Zero(), now);
  // From the state, at the counters' speed (the state's own is one increment's, and jitters).
  const core::Pose2 at_counters_speed = state.world_from_vehicle * core::Pose2::Exp(Eigen::Vector3d(20.0, 0.0, 0.002));
  EXPECT_LT(core::Distance(latest.world_from_vehicle, at_counters_speed), 0.01);
  EXPECT_EQ(latest.carried, core::Duration::zero());
  EXPECT_EQ(latest.extrapolated, milliseconds(20));

  const estimation::MotionState older = vehicle.State(900.0, 0.1);
  output.Add(vehicle.Drive(10, 1000.0, 0.1));
  EXPECT_GT(output.At(older, Eigen::Vector2d::Zero(), vehicle.time()).carried, core::Duration::zero());
  output.Forget();
  const OutputPose::Prediction forgotten = output.At(older, Eigen::Vector2d::Zero(), vehicle.time());
  EXPECT_EQ(forgotten.carried, core::Duration::zero());
  EXPECT_LT(core::Distance(forgotten.world_from_vehicle, older.PoseAt(vehicle.time())), 1e-9);
  // After Forget the next sample only seeds the counters again.
  output.Add(vehicle.Drive(10, 1000.0, 0.1));
  EXPECT_EQ(output.At(older, Eigen::Vector2d::Zero(), vehicle.time()).carried, core::Duration::zero());
}

// A vehicle creeping at 100 mm/s brakes to a stop at 3 m/s^2; its counters then stand still,
// and the stamper does not pass that on for half a second (they last changed as a moving
// vehicle's do). Read unchanged, they hold the written pose within the braking distance of
// the speed the counters last showed; not read, it is extrapolated on at that speed.
TEST(OutputPose, CountersReadUnchangedAfterAStopHoldTheVehicleWithinItsBrakingDistance) {
  Vehicle vehicle(Eigen::Vector2d::Zero());
  OutputPose reading(Differential()), blind(Differential());
  const auto add = [&](const dataset::EncoderSample& sample) {
    reading.Add(sample);
    blind.Add(sample);
  };
  for (int i = 0; i < 5; ++i) add(vehicle.Drive(10, 100.0, 0.0));
  for (const double v : {70.0, 40.0, 10.0}) add(vehicle.Drive(10, v, 0.0));
  const estimation::MotionState state = vehicle.State(10.0, 0.0);
  dataset::EncoderSample still;
  for (int i = 0; i < 10; ++i) {
    still = vehicle.Drive(10, 0.0, 0.0);
    reading.Read(still.time, still.counts);
  }
  const core::Pose2 stop = vehicle.pose();
  const double held = core::Distance(reading.At(state, Eigen::Vector2d::Zero(), still.time).world_from_vehicle, stop);
  const double extrapolated =
      core::Distance(blind.At(state, Eigen::Vector2d::Zero(), still.time).world_from_vehicle, stop);
  std::printf("100 ms after the stop: %.2f mm past it with the reads, %.2f mm without\n", held, extrapolated);
  EXPECT_LT(held, 0.6) << "the last 40 ms averaged 55 mm/s: 0.5 mm to brake from it";
  EXPECT_GT(extrapolated, 4.0);
}

// The same reads when the PLC stalls at speed (its counters frozen for 60 ms while the vehicle
// drives on at 1.5 m/s): the braking distance, 375 mm, does not bind, and the pose goes on.
TEST(OutputPose, CountersFrozenAtSpeedAreExtrapolatedAsBefore) {
  Vehicle vehicle(Eigen::Vector2d::Zero());
  OutputPose output(Differential());
  dataset::EncoderSample last;
  for (int i = 0; i < 6; ++i) {
    last = vehicle.Drive(10, 1500.0, 0.0);
    output.Add(last);
  }
  const estimation::MotionState state = vehicle.State(1500.0, 0.0);
  for (int i = 0; i < 6; ++i) {
    vehicle.Drive(10, 1500.0, 0.0);
    output.Read(vehicle.time(), last.counts);
  }
  EXPECT_LT(core::Distance(output.At(state, Eigen::Vector2d::Zero(), vehicle.time()).world_from_vehicle, vehicle.pose()),
            0.01);
}

}  // namespace
}  // namespace mosaicloc::runtime
