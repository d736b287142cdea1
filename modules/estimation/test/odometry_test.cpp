#include "mosaicloc/estimation/odometry.hpp"

#include <cmath>
#include <limits>
#include <numbers>

#include <gtest/gtest.h>

namespace mosaicloc::estimation {
namespace {

using core::Timestamp;

DiffDriveOptions Options() {
  DiffDriveOptions options;
  options.wheels.left_wheel_radius_mm = options.wheels.right_wheel_radius_mm = 100.0 / std::numbers::pi;  // 200 mm/rev
  options.wheels.ticks_per_revolution = 2000;                                                   // 0.1 mm/tick
  options.wheels.track_width_mm = 500.0;
  return options;
}

Timestamp Ms(std::int64_t ms) { return Timestamp::FromNanoseconds(ms * 1'000'000); }

TEST(TickDelta, HandlesWrapAround) {
  constexpr std::int32_t kMax = std::numeric_limits<std::int32_t>::max();
  constexpr std::int32_t kMin = std::numeric_limits<std::int32_t>::min();
  EXPECT_EQ(TickDelta(10, 25), 15);
  EXPECT_EQ(TickDelta(25, 10), -15);
  EXPECT_EQ(TickDelta(kMax - 4, kMin + 5), 10);
  EXPECT_EQ(TickDelta(kMin + 5, kMax - 4), -10);
}

TEST(DiffDriveOdometry, StraightLineAcrossCounterWrap) {
  DiffDriveOdometry odometry(Options());
  std::int32_t ticks = std::numeric_limits<std::int32_t>::max() - 5000;
  ASSERT_TRUE(odometry.Update(Ms(0), ticks, ticks).ok());
  for (int i = 1; i <= 100; ++i) {
    ticks = static_cast<std::int32_t>(static_cast<std::uint32_t>(ticks) + 100u);  // 10 mm per 10 ms
    const auto increment = odometry.Update(Ms(10 * i), ticks, ticks);
    ASSERT_TRUE(increment.ok());
    EXPECT_NEAR(increment.value().forward_speed_mps, 1.0, 1e-12);
  }
  EXPECT_NEAR(odometry.world_from_vehicle().x_mm(), 1000.0, 1e-9);
  EXPECT_NEAR(odometry.world_from_vehicle().y_mm(), 0.0, 1e-9);
  // Variance grows along track only for a straight run with an initially certain heading...
  EXPECT_GT(odometry.covariance()(0, 0), 0.0);
  // ...and heading variance grows linearly with distance: k (|dr| + |dl|) / b^2 per step.
  EXPECT_NEAR(odometry.covariance()(2, 2), 100 * 0.01 * 20.0 / (500.0 * 500.0), 1e-15);
}

TEST(DiffDriveOdometry, TurnInPlaceAndArc) {
  DiffDriveOdometry odometry(Options());
  ASSERT_TRUE(odometry.Update(Ms(0), 0, 0).ok());
  // Quarter turn in place: each wheel travels b * pi / 4 = 392.699 mm = 3926.99 ticks.
  const double quarter_ticks = 500.0 * std::numbers::pi / 4.0 / 0.1;
  const auto t = static_cast<std::int32_t>(std::lround(quarter_ticks));
  ASSERT_TRUE(odometry.Update(Ms(1000), -t, t).ok());
  EXPECT_NEAR(odometry.world_from_vehicle().yaw_rad(), std::numbers::pi / 2, 2e-4);
  EXPECT_NEAR(odometry.world_from_vehicle().translation_mm().norm(), 0.0, 1e-9);

  // An arc of radius 1000 mm through 90 degrees in 100 steps ends at (R, R) from its start.
  DiffDriveOdometry arc(Options());
  ASSERT_TRUE(arc.Update(Ms(0), 0, 0).ok());
  const double radius = 1000.0;
  const double step_rad = std::numbers::pi / 2 / 100.0;
  double left = 0.0;
  double right = 0.0;
  for (int i = 1; i <= 100; ++i) {
    left += (radius - 250.0) * step_rad / 0.1;
    right += (radius + 250.0) * step_rad / 0.1;
    ASSERT_TRUE(arc.Update(Ms(10 * i), static_cast<std::int32_t>(std::lround(left)),
                           static_cast<std::int32_t>(std::lround(right))).ok());
  }
  EXPECT_NEAR(arc.world_from_vehicle().x_mm(), radius, 0.2);
  EXPECT_NEAR(arc.world_from_vehicle().y_mm(), radius, 0.2);
  EXPECT_NEAR(arc.world_from_vehicle().yaw_rad(), std::numbers::pi / 2, 1e-3);
}

TEST(DiffDriveOdometry, RejectsGlitchesAndTimeReversal) {
  DiffDriveOdometry odometry(Options());
  ASSERT_TRUE(odometry.Update(Ms(0), 0, 0).ok());
  ASSERT_TRUE(odometry.Update(Ms(10), 100, 100).ok());
  const auto backwards = odometry.Update(Ms(10), 200, 200);
  ASSERT_FALSE(backwards.ok());
  EXPECT_EQ(backwards.error(), OdometryFailure::kNotIncreasingTime);
  // 1e6 ticks = 100 m in 10 ms.
  const auto jump = odometry.Update(Ms(20), 1'000'100, 100);
  ASSERT_FALSE(jump.ok());
  EXPECT_EQ(jump.error(), OdometryFailure::kImplausibleJump);
  EXPECT_NEAR(odometry.world_from_vehicle().x_mm(), 10.0, 1e-9);
  // The glitched sample became the reference: the next good one integrates normally.
  ASSERT_TRUE(odometry.Update(Ms(30), 1'000'200, 200).ok());
  EXPECT_NEAR(odometry.world_from_vehicle().x_mm(), 20.0, 1e-9);
}

TEST(DiffDriveOdometry, RejectsBadOptions) {
  DiffDriveOptions options = Options();
  options.wheels.track_width_mm = 0.0;
  EXPECT_THROW(DiffDriveOdometry{options}, core::Error);
}

}  // namespace
}  // namespace mosaicloc::estimation
