#include "mosaicloc/sim/encoders.hpp"

#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "mosaicloc/estimation/odometry.hpp"

namespace mosaicloc::sim {
namespace {

core::Timestamp Ms(std::int64_t ms) { return core::Timestamp::FromNanoseconds(ms * 1'000'000); }

TEST(EncoderModel, StraightRunCountsWithRadiusErrorAndWraps) {
  EncoderOptions options;
  options.slip_std = 0.0;
  options.left_radius_error = 0.01;
  options.right_radius_error = 0.01;
  EncoderModel model(options, 1);
  const auto first = model.Step(Ms(0), core::Pose2());
  EXPECT_EQ(first.counts.left_ticks, options.initial_left_ticks);
  // 30 m forward: each wheel turns 30000 / (2 pi 75.75) revolutions.
  const auto last = model.Step(Ms(30000), core::Pose2(30000.0, 0.0, 0.0));
  const double expected = 30000.0 / (2.0 * std::numbers::pi * 75.0 * 1.01) * 4096.0;
  const std::int64_t left_delta = estimation::TickDelta(first.counts.left_ticks, last.counts.left_ticks);
  EXPECT_NEAR(static_cast<double>(left_delta), expected, 1.0);
  // The counter went past the int32 maximum.
  EXPECT_LT(last.counts.left_ticks, 0);
}

TEST(EncoderModel, DeadReckoningShowsTheScaleError) {
  // With a 1 % larger true radius, odometry with the nominal radius under-reads by ~1 %.
  EncoderOptions options;
  options.slip_std = 0.0;
  options.left_radius_error = options.right_radius_error = 0.01;
  options.track_width_error = 0.0;
  EncoderModel model(options, 1);
  estimation::OdometryOptions odometry_options;
  estimation::WheelOdometry odometry(odometry_options);
  for (int i = 0; i <= 1000; ++i) {
    const auto sample = model.Step(Ms(10 * i), core::Pose2(5.0 * i, 0.0, 0.0));
    ASSERT_TRUE(odometry.Update(sample.time, sample.counts).ok());
  }
  EXPECT_NEAR(odometry.world_from_vehicle().x_mm(), 5000.0 / 1.01, 0.5);
}

TEST(EncoderModel, TurnInPlaceUsesTheTrueTrackWidth) {
  EncoderOptions options;
  options.slip_std = 0.0;
  options.left_radius_error = options.right_radius_error = 0.0;
  options.track_width_error = 0.02;
  EncoderModel model(options, 1);
  estimation::WheelOdometry odometry(estimation::OdometryOptions{});
  for (int i = 0; i <= 100; ++i) {
    const auto sample = model.Step(Ms(10 * i), core::Pose2(0.0, 0.0, std::numbers::pi / 2 * i / 100.0));
    ASSERT_TRUE(odometry.Update(sample.time, sample.counts).ok());
  }
  // Wheels travel 2 % further than the nominal track width predicts.
  EXPECT_NEAR(odometry.world_from_vehicle().yaw_rad(), std::numbers::pi / 2 * 1.02, 2e-3);
}

TEST(EncoderModel, SameSeedSameCounts) {
  EncoderOptions options;
  EncoderModel a(options, 5);
  EncoderModel b(options, 5);
  EncoderModel c(options, 6);
  bool any_different = false;
  for (int i = 0; i < 100; ++i) {
    const core::Pose2 pose(3.0 * i, 0.1 * i, 0.001 * i);
    const auto sa = a.Step(Ms(10 * i), pose);
    const auto sb = b.Step(Ms(10 * i), pose);
    const auto sc = c.Step(Ms(10 * i), pose);
    EXPECT_EQ(sa.counts.left_ticks, sb.counts.left_ticks);
    EXPECT_EQ(sa.counts.right_ticks, sb.counts.right_ticks);
    any_different = any_different || sa.counts.left_ticks != sc.counts.left_ticks;
  }
  EXPECT_TRUE(any_different);
}

// A tricycle on an arc of radius R: the drive wheel, l ahead, rolls on a circle of radius
// hypot(R, l) at the angle atan(l / R); the steering encoder reads that angle less its true
// zero, and the drive counter the wheel's path through the true radius. Odometry with the
// calibration the dataset records finds the offset and the scale as the errors it has.
TEST(EncoderModel, TricycleReadsTheSteeringAngleAndTheDriveWheelsPath) {
  EncoderOptions options;
  options.nominal.kind = core::DriveKind::kTricycle;
  options.nominal.wheelbase_mm = 1200.0;
  options.nominal.drive_wheel_radius_mm = 100.0;
  options.nominal.steering_ticks_per_revolution = 1 << 20;
  options.slip_std = 0.0;
  options.wheelbase_error = 0.0;
  options.drive_radius_error = 0.01;
  options.steering_offset_error_deg = 0.5;
  options.steering_backlash_deg = 0.0;
  EncoderModel model(options, 1);
  const double radius = 2000.0, step_rad = 0.005;
  const auto pose = [&](int i) {
    const double a = step_rad * i;
    return core::Pose2(radius * std::sin(a), radius * (1.0 - std::cos(a)), a);
  };
  std::vector<dataset::EncoderSample> samples;
  for (int i = 0; i <= 200; ++i) samples.push_back(model.Step(Ms(10 * i), pose(i), pose(i) * core::Pose2(1.0, 0.0, 1.0 / radius)));
  const double phi = std::atan(1200.0 / radius);
  const double read_rad = 2.0 * std::numbers::pi * samples[100].counts.steering_ticks / static_cast<double>(1 << 20);
  EXPECT_NEAR(read_rad, phi - 0.5 * std::numbers::pi / 180.0, 1e-5);
  const double wheel_path_mm = std::hypot(radius, 1200.0) * step_rad * 200;
  const double turns = estimation::TickDelta(samples.front().counts.drive_ticks, samples.back().counts.drive_ticks) / 4096.0;
  EXPECT_NEAR(turns * 2.0 * std::numbers::pi * 101.0, wheel_path_mm, 0.2);
  EXPECT_EQ(samples.back().counts.left_ticks, 0);  // not a differential drive's counters

  // Odometry with the calibrated (nominal) geometry: short by 1 %, and turning too little.
  estimation::OdometryOptions odometry_options;
  odometry_options.wheels = options.nominal;
  estimation::WheelOdometry odometry(odometry_options);
  for (const auto& sample : samples) ASSERT_TRUE(odometry.Update(sample.time, sample.counts).ok());
  EXPECT_LT(odometry.world_from_vehicle().yaw_rad(), step_rad * 200);
  odometry_options.wheels.drive_wheel_radius_mm = 101.0;
  odometry_options.wheels.steering_offset_deg = 0.5;
  estimation::WheelOdometry corrected(odometry_options);
  for (const auto& sample : samples) ASSERT_TRUE(corrected.Update(sample.time, sample.counts).ok());
  EXPECT_LT(core::Distance(corrected.world_from_vehicle(), pose(200)), 0.5);
  EXPECT_NEAR(corrected.world_from_vehicle().yaw_rad(), step_rad * 200, 1e-4);
}

// A mecanum vehicle crabbing while it turns: the four counters follow the kinematics, so that
// odometry on the true geometry drives the true path; with rollers that slip sideways the
// odometry overshoots the sideways motion by 1 / (1 - slip), and the sideways scale mends it.
TEST(EncoderModel, MecanumWheelsFollowTheKinematicsAndTheRollersSlipSideways) {
  EncoderOptions options;
  options.nominal.kind = core::DriveKind::kMecanum;
  options.nominal.mecanum_wheel_radius_mm = 50.0;
  options.nominal.track_width_mm = 560.0;
  options.nominal.wheelbase_mm = 480.0;
  options.slip_std = 0.0;
  options.mecanum_radius_error = 0.0;
  options.track_width_error = options.wheelbase_error = 0.0;
  options.lateral_slip = 0.0;
  // Body motion per 10 ms step: 9 mm forward, 6 mm to the left, turning 2 mrad.
  const core::Pose2 step = core::Pose2::Exp({9.0, 6.0, 0.002});
  const auto drive = [&](const EncoderOptions& o) {
    EncoderModel model(o, 1);
    std::vector<dataset::EncoderSample> samples;
    core::Pose2 pose;
    for (int i = 0; i <= 300; ++i, pose = pose * step) samples.push_back(model.Step(Ms(10 * i), pose));
    return std::make_pair(samples, pose * step.Inverse());
  };
  const auto [exact, truth] = drive(options);
  EXPECT_EQ(exact.back().counts.drive_ticks, 0);  // not a tricycle's counters
  estimation::OdometryOptions odometry_options;
  odometry_options.wheels = options.nominal;
  estimation::WheelOdometry odometry(odometry_options);
  for (const auto& sample : exact) ASSERT_TRUE(odometry.Update(sample.time, sample.counts).ok());
  EXPECT_LT(core::Distance(odometry.world_from_vehicle(), truth), 0.2) << "quantization only";
  EXPECT_NEAR(odometry.world_from_vehicle().yaw_rad(), truth.yaw_rad(), 1e-4);

  options.lateral_slip = 0.05;
  const auto [slipping, truth_again] = drive(options);
  estimation::WheelOdometry overshooting(odometry_options);
  estimation::OdometryIncrement last;
  double sideways_mm = 0.0, mended_mm = 0.0;
  for (const auto& sample : slipping) {
    const auto increment = overshooting.Update(sample.time, sample.counts);
    ASSERT_TRUE(increment.ok());
    if (!increment.value().travel.measured()) continue;
    sideways_mm += increment.value().travel.Motion(Eigen::Vector2d::Zero()).y();
    mended_mm += increment.value().travel.Motion(Eigen::Vector2d(0.0, -0.05)).y();
  }
  EXPECT_NEAR(sideways_mm, 300 * 6.0 / 0.95, 0.5);
  EXPECT_NEAR(mended_mm, 300 * 6.0, 0.5);
}

}  // namespace
}  // namespace mosaicloc::sim
