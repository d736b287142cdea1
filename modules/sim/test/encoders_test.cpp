#include "mosaicloc/sim/encoders.hpp"

#include <cmath>
#include <numbers>

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
  EXPECT_EQ(first.left_ticks, options.initial_left_ticks);
  // 30 m forward: each wheel turns 30000 / (2 pi 75.75) revolutions.
  const auto last = model.Step(Ms(30000), core::Pose2(30000.0, 0.0, 0.0));
  const double expected = 30000.0 / (2.0 * std::numbers::pi * 75.0 * 1.01) * 4096.0;
  const std::int64_t left_delta = estimation::TickDelta(first.left_ticks, last.left_ticks);
  EXPECT_NEAR(static_cast<double>(left_delta), expected, 1.0);
  // The counter went past the int32 maximum.
  EXPECT_LT(last.left_ticks, 0);
}

TEST(EncoderModel, DeadReckoningShowsTheScaleError) {
  // With a 1 % larger true radius, odometry with the nominal radius under-reads by ~1 %.
  EncoderOptions options;
  options.slip_std = 0.0;
  options.left_radius_error = options.right_radius_error = 0.01;
  options.track_width_error = 0.0;
  EncoderModel model(options, 1);
  estimation::DiffDriveOptions odometry_options;
  estimation::DiffDriveOdometry odometry(odometry_options);
  for (int i = 0; i <= 1000; ++i) {
    const auto sample = model.Step(Ms(10 * i), core::Pose2(5.0 * i, 0.0, 0.0));
    ASSERT_TRUE(odometry.Update(sample.time, sample.left_ticks, sample.right_ticks).ok());
  }
  EXPECT_NEAR(odometry.world_from_vehicle().x_mm(), 5000.0 / 1.01, 0.5);
}

TEST(EncoderModel, TurnInPlaceUsesTheTrueTrackWidth) {
  EncoderOptions options;
  options.slip_std = 0.0;
  options.left_radius_error = options.right_radius_error = 0.0;
  options.track_width_error = 0.02;
  EncoderModel model(options, 1);
  estimation::DiffDriveOdometry odometry(estimation::DiffDriveOptions{});
  for (int i = 0; i <= 100; ++i) {
    const auto sample = model.Step(Ms(10 * i), core::Pose2(0.0, 0.0, std::numbers::pi / 2 * i / 100.0));
    ASSERT_TRUE(odometry.Update(sample.time, sample.left_ticks, sample.right_ticks).ok());
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
    EXPECT_EQ(sa.left_ticks, sb.left_ticks);
    EXPECT_EQ(sa.right_ticks, sb.right_ticks);
    any_different = any_different || sa.left_ticks != sc.left_ticks;
  }
  EXPECT_TRUE(any_different);
}

}  // namespace
}  // namespace mosaicloc::sim
