#include "mosaicloc/estimation/odometry.hpp"

#include <cmath>
#include <limits>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

namespace mosaicloc::estimation {
namespace {

using core::Timestamp;

OdometryOptions Options() {
  OdometryOptions options;
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

TEST(WheelOdometry, StraightLineAcrossCounterWrap) {
  WheelOdometry odometry(Options());
  std::int32_t ticks = std::numeric_limits<std::int32_t>::max() - 5000;
  ASSERT_TRUE(odometry.Update(Ms(0), {ticks, ticks}).ok());
  for (int i = 1; i <= 100; ++i) {
    ticks = static_cast<std::int32_t>(static_cast<std::uint32_t>(ticks) + 100u);  // 10 mm per 10 ms
    const auto increment = odometry.Update(Ms(10 * i), {ticks, ticks});
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

TEST(WheelOdometry, TurnInPlaceAndArc) {
  WheelOdometry odometry(Options());
  ASSERT_TRUE(odometry.Update(Ms(0), {0, 0}).ok());
  // Quarter turn in place: each wheel travels b * pi / 4 = 392.699 mm = 3926.99 ticks.
  const double quarter_ticks = 500.0 * std::numbers::pi / 4.0 / 0.1;
  const auto t = static_cast<std::int32_t>(std::lround(quarter_ticks));
  ASSERT_TRUE(odometry.Update(Ms(1000), {-t, t}).ok());
  EXPECT_NEAR(odometry.world_from_vehicle().yaw_rad(), std::numbers::pi / 2, 2e-4);
  EXPECT_NEAR(odometry.world_from_vehicle().translation_mm().norm(), 0.0, 1e-9);

  // An arc of radius 1000 mm through 90 degrees in 100 steps ends at (R, R) from its start.
  WheelOdometry arc(Options());
  ASSERT_TRUE(arc.Update(Ms(0), {0, 0}).ok());
  const double radius = 1000.0;
  const double step_rad = std::numbers::pi / 2 / 100.0;
  double left = 0.0;
  double right = 0.0;
  for (int i = 1; i <= 100; ++i) {
    left += (radius - 250.0) * step_rad / 0.1;
    right += (radius + 250.0) * step_rad / 0.1;
    ASSERT_TRUE(arc.Update(Ms(10 * i), {static_cast<std::int32_t>(std::lround(left)),
                                        static_cast<std::int32_t>(std::lround(right))})
                    .ok());
  }
  EXPECT_NEAR(arc.world_from_vehicle().x_mm(), radius, 0.2);
  EXPECT_NEAR(arc.world_from_vehicle().y_mm(), radius, 0.2);
  EXPECT_NEAR(arc.world_from_vehicle().yaw_rad(), std::numbers::pi / 2, 1e-3);
}

TEST(WheelOdometry, RejectsGlitchesAndTimeReversal) {
  WheelOdometry odometry(Options());
  ASSERT_TRUE(odometry.Update(Ms(0), {0, 0}).ok());
  ASSERT_TRUE(odometry.Update(Ms(10), {100, 100}).ok());
  const auto backwards = odometry.Update(Ms(10), {200, 200});
  ASSERT_FALSE(backwards.ok());
  EXPECT_EQ(backwards.error(), OdometryFailure::kNotIncreasingTime);
  // 1e6 ticks = 100 m in 10 ms.
  const auto jump = odometry.Update(Ms(20), {1'000'100, 100});
  ASSERT_FALSE(jump.ok());
  EXPECT_EQ(jump.error(), OdometryFailure::kImplausibleJump);
  EXPECT_NEAR(odometry.world_from_vehicle().x_mm(), 10.0, 1e-9);
  // The glitched sample became the reference: the next good one integrates normally.
  ASSERT_TRUE(odometry.Update(Ms(30), {1'000'200, 200}).ok());
  EXPECT_NEAR(odometry.world_from_vehicle().x_mm(), 20.0, 1e-9);
}

// A tricycle: 0.1 mm per drive tick, 1/4096 of a turn per steering count, a 1200 mm wheelbase.
OdometryOptions Tricycle() {
  OdometryOptions options;
  options.wheels.kind = core::DriveKind::kTricycle;
  options.wheels.drive_wheel_radius_mm = 100.0 / std::numbers::pi;
  options.wheels.ticks_per_revolution = 2000;
  options.wheels.wheelbase_mm = 1200.0;
  options.wheels.steering_ticks_per_revolution = 4096;
  return options;
}

TEST(WheelOdometry, TricycleStraightArcAndPivot) {
  // Straight: the steering at its zero, 1 m of drive wheel travel.
  WheelOdometry straight(Tricycle());
  ASSERT_TRUE(straight.Update(Ms(0), {.drive_ticks = 0, .steering_ticks = 0}).ok());
  ASSERT_TRUE(straight.Update(Ms(1000), {.drive_ticks = 10000, .steering_ticks = 0}).ok());
  EXPECT_NEAR(straight.world_from_vehicle().x_mm(), 1000.0, 1e-9);
  EXPECT_NEAR(straight.world_from_vehicle().yaw_rad(), 0.0, 1e-12);

  // Steered by phi: the fixed axle's centre turns on a circle of radius l / tan(phi). A quarter
  // of it in 100 steps ends at (R, R).
  const std::int32_t steering = 256;  // 22.5 degrees
  const double phi = 2.0 * std::numbers::pi * steering / 4096.0;
  const double radius = 1200.0 / std::tan(phi);
  const double drive_per_step = radius * (std::numbers::pi / 2.0 / 100.0) / std::cos(phi) / 0.1;  // ticks
  WheelOdometry arc(Tricycle());
  ASSERT_TRUE(arc.Update(Ms(0), {.drive_ticks = 0, .steering_ticks = steering}).ok());
  double drive = 0.0;
  for (int i = 1; i <= 100; ++i) {
    drive += drive_per_step;
    ASSERT_TRUE(arc.Update(Ms(10 * i), {.drive_ticks = static_cast<std::int32_t>(std::lround(drive)),
                                        .steering_ticks = steering})
                    .ok());
  }
  EXPECT_NEAR(arc.world_from_vehicle().x_mm(), radius, 0.3);
  EXPECT_NEAR(arc.world_from_vehicle().y_mm(), radius, 0.3);
  EXPECT_NEAR(arc.world_from_vehicle().yaw_rad(), std::numbers::pi / 2, 1e-4);

  // Steered a quarter turn the drive wheel pivots the vehicle about the fixed axle's centre.
  WheelOdometry pivot(Tricycle());
  ASSERT_TRUE(pivot.Update(Ms(0), {.drive_ticks = 0, .steering_ticks = 1024}).ok());
  const auto quarter = static_cast<std::int32_t>(std::lround(1200.0 * std::numbers::pi / 2.0 / 0.1));
  ASSERT_TRUE(pivot.Update(Ms(1000), {.drive_ticks = quarter, .steering_ticks = 1024}).ok());
  EXPECT_NEAR(pivot.world_from_vehicle().yaw_rad(), std::numbers::pi / 2, 1e-4);
  EXPECT_NEAR(pivot.world_from_vehicle().translation_mm().norm(), 0.0, 1e-9);
}

// The calibrated steering offset is the angle at count 0; the steering reading's error makes
// the heading uncertain in proportion to the distance driven, not while standing.
TEST(WheelOdometry, TricycleSteeringOffsetAndItsUncertainty) {
  OdometryOptions options = Tricycle();
  options.wheels.steering_offset_deg = 22.5;
  WheelOdometry offset(options);
  ASSERT_TRUE(offset.Update(Ms(0), {.drive_ticks = 0, .steering_ticks = 0}).ok());
  const auto increment = offset.Update(Ms(10), {.drive_ticks = 100, .steering_ticks = 0});
  ASSERT_TRUE(increment.ok());
  EXPECT_NEAR(increment.value().yaw_rate_radps, 10.0 * std::sin(std::numbers::pi / 8) / 1200.0 * 100.0, 1e-9);

  WheelOdometry standing(Tricycle());
  ASSERT_TRUE(standing.Update(Ms(0), {.drive_ticks = 5, .steering_ticks = 100}).ok());
  ASSERT_TRUE(standing.Update(Ms(10), {.drive_ticks = 5, .steering_ticks = 300}).ok());
  EXPECT_EQ(standing.covariance(), Eigen::Matrix3d::Zero()) << "steering without driving moves nothing";
  ASSERT_TRUE(standing.Update(Ms(1010), {.drive_ticks = 10005, .steering_ticks = 300}).ok());
  const double sigma_rad = 0.05 * std::numbers::pi / 180.0;
  const double phi = 2.0 * std::numbers::pi * 300 / 4096.0;
  // Heading variance: the wheel's k |s| (sin phi / l)^2 plus the angle's sigma^2 (s cos phi / l)^2.
  const double expected = 0.01 * 1000.0 * std::pow(std::sin(phi) / 1200.0, 2) +
                          sigma_rad * sigma_rad * std::pow(1000.0 * std::cos(phi) / 1200.0, 2);
  EXPECT_NEAR(standing.covariance()(2, 2), expected, 1e-12);
}

// The counts' quantization: whole ticks at both ends of a stretch of any length. Drawn: each
// wheel's encoder phase at the start and a travel of up to 40 ticks, counted as the encoder
// counts (whole ticks passed); the motion's error through the kinematics.
TEST(WheelOdometry, TickQuantizationIsTheCountsErrorOverAnyStretch) {
  core::WheelGeometry wheels;  // differential, 75 mm wheels, 4096 ticks, track 500 mm
  const double q = wheels.TicksToMm(wheels.left_wheel_radius_mm, 1), b = wheels.track_width_mm;
  std::mt19937 random(5);
  std::uniform_real_distribution<double> phase(0.0, 1.0), travel(0.0, 40.0);
  const auto counted_error_mm = [&] {
    const double start = phase(random), ticks = travel(random);
    return q * (std::floor(start + ticks) - ticks);
  };
  Eigen::Matrix3d sampled = Eigen::Matrix3d::Zero();
  const int n = 200000;
  for (int i = 0; i < n; ++i) {
    const double left = counted_error_mm(), right = counted_error_mm();
    const Eigen::Vector3d e(0.5 * (left + right), 0.0, (right - left) / b);
    sampled += e * e.transpose() / n;
  }
  const Eigen::Matrix3d model = TickQuantizationCovariance(wheels);
  EXPECT_NEAR(model(0, 0), q * q / 12.0, 1e-15);
  EXPECT_NEAR(sampled(0, 0), model(0, 0), 0.02 * model(0, 0));
  EXPECT_NEAR(sampled(2, 2), model(2, 2), 0.02 * model(2, 2));
  EXPECT_NEAR(sampled(0, 2), model(0, 2), 0.02 * model(2, 2) * b);
  EXPECT_EQ(model(1, 1), 0.0);
  // A tick is 0.115 mm here: the counts' error is 33 micrometres along the heading, whatever
  // the distance.
  EXPECT_NEAR(std::sqrt(model(0, 0)), 0.0332, 0.0005);
}

OdometryOptions Mecanum() {
  OdometryOptions options;
  options.wheels.kind = core::DriveKind::kMecanum;
  options.wheels.mecanum_wheel_radius_mm = 50.0;
  options.wheels.track_width_mm = 560.0;
  options.wheels.wheelbase_mm = 480.0;
  options.wheels.ticks_per_revolution = 4096;
  return options;
}

// The four wheels of a mecanum vehicle: forwards all turn alike; sideways (to the left) the
// front left and rear right turn back; turning, the left side turns back.
TEST(WheelOdometry, MecanumForwardSidewaysAndTurning) {
  const OdometryOptions options = Mecanum();
  const double mm_per_tick = 2.0 * std::numbers::pi * 50.0 / 4096.0, l = 0.5 * (560.0 + 480.0);
  const auto counts = [](std::int32_t fl, std::int32_t fr, std::int32_t rl, std::int32_t rr) {
    core::EncoderCounts c;
    c.left_ticks = fl;
    c.right_ticks = fr;
    c.rear_left_ticks = rl;
    c.rear_right_ticks = rr;
    return c;
  };
  for (const auto& [moved, expected] :
       {std::pair{counts(1000, 1000, 1000, 1000), Eigen::Vector3d(1000 * mm_per_tick, 0.0, 0.0)},
        std::pair{counts(-1000, 1000, 1000, -1000), Eigen::Vector3d(0.0, 1000 * mm_per_tick, 0.0)},
        std::pair{counts(-1000, 1000, -1000, 1000), Eigen::Vector3d(0.0, 0.0, 1000 * mm_per_tick / l)}}) {
    WheelOdometry odometry(options);
    ASSERT_TRUE(odometry.Update(Ms(0), counts(0, 0, 0, 0)).ok());
    const auto increment = odometry.Update(Ms(100), moved);
    ASSERT_TRUE(increment.ok());
    const Eigen::Vector3d twist = increment.value().previous_from_current.Log();
    EXPECT_LT((twist - expected).norm(), 1e-9) << twist.transpose();
    EXPECT_NEAR(increment.value().lateral_speed_mps, expected.y() / 0.1 * 1e-3, 1e-12);
    // Each wheel's variance k |d|: sideways, dy = (-fl + fr + rl - rr) / 4 has k |d| / 4.
    const double k_d = options.wheel_variance_mm * 1000 * mm_per_tick;
    if (expected.y() > 0.0) {
      EXPECT_NEAR(odometry.covariance()(1, 1), k_d / 4.0, 1e-12);
      // Forward as uncertain (the same four wheels), and the turn's uncertainty over the arc.
      const double turn_variance = k_d / (4.0 * l * l);
      EXPECT_NEAR(odometry.covariance()(0, 0), k_d / 4.0 + std::pow(0.5 * expected.y(), 2) * turn_variance, 1e-12);
    }
  }
  // A wheel that jumps is a glitch, whichever it is.
  WheelOdometry odometry(options);
  ASSERT_TRUE(odometry.Update(Ms(0), counts(0, 0, 0, 0)).ok());
  EXPECT_FALSE(odometry.Update(Ms(10), counts(0, 0, 0, 4000000)).ok());
}

TEST(WheelOdometry, RejectsBadOptions) {
  OdometryOptions options = Options();
  options.wheels.track_width_mm = 0.0;
  EXPECT_THROW(WheelOdometry{options}, core::Error);
}

}  // namespace
}  // namespace mosaicloc::estimation
