#include "mosaicloc/core/pose2.hpp"

#include <cmath>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

namespace mosaicloc::core {
namespace {

constexpr double kPi = std::numbers::pi;

void ExpectPoseNear(const Pose2& a, const Pose2& b, double tol_mm = 1e-9, double tol_rad = 1e-12) {
  EXPECT_NEAR(a.x_mm(), b.x_mm(), tol_mm);
  EXPECT_NEAR(a.y_mm(), b.y_mm(), tol_mm);
  EXPECT_NEAR(YawDifference(a, b), 0.0, tol_rad);
}

TEST(WrapAngle, MapsIntoHalfOpenInterval) {
  EXPECT_DOUBLE_EQ(WrapAngle(0.0), 0.0);
  EXPECT_DOUBLE_EQ(WrapAngle(kPi), kPi);
  EXPECT_DOUBLE_EQ(WrapAngle(-kPi), kPi);  // -pi is excluded
  EXPECT_NEAR(WrapAngle(3.0 * kPi), kPi, 1e-12);
  EXPECT_NEAR(WrapAngle(-0.5 * kPi - 4.0 * kPi), -0.5 * kPi, 1e-12);
  EXPECT_NEAR(WrapAngle(2.0 * kPi + 0.1), 0.1, 1e-12);
}

TEST(Pose2, ComposeKnownValues) {
  const Pose2 world_from_vehicle(1000.0, 2000.0, kPi / 2);
  const Pose2 vehicle_from_camera(300.0, 0.0, 0.0);
  const Pose2 world_from_camera = world_from_vehicle * vehicle_from_camera;
  // Facing +y, 300 mm forward moves along +y.
  ExpectPoseNear(world_from_camera, Pose2(1000.0, 2300.0, kPi / 2));
  const Eigen::Vector2d p_world = world_from_camera * Eigen::Vector2d(10.0, 0.0);
  EXPECT_NEAR(p_world.x(), 1000.0, 1e-9);
  EXPECT_NEAR(p_world.y(), 2310.0, 1e-9);
}

TEST(Pose2, YawIsWrappedOnConstruction) {
  EXPECT_NEAR(Pose2(0, 0, 3 * kPi / 2).yaw_rad(), -kPi / 2, 1e-12);
  EXPECT_NEAR((Pose2(0, 0, 3.0) * Pose2(0, 0, 3.0)).yaw_rad(), 6.0 - 2 * kPi, 1e-12);
}

TEST(Pose2, ExpOfPureRotationAndTranslation) {
  ExpectPoseNear(Pose2::Exp({5.0, -2.0, 0.0}), Pose2(5.0, -2.0, 0.0));
  ExpectPoseNear(Pose2::Exp({0.0, 0.0, 1.0}), Pose2(0.0, 0.0, 1.0));
  // Quarter circle of radius R: forward speed R*pi/2 with omega pi/2 ends at (R, R).
  const double radius_mm = 500.0;
  ExpectPoseNear(Pose2::Exp({radius_mm * kPi / 2, 0.0, kPi / 2}), Pose2(radius_mm, radius_mm, kPi / 2));
}

TEST(Pose2, InterpolateOnArcIsExact) {
  const double radius_mm = 800.0;
  const Pose2 start(100.0, 50.0, 0.3);
  const Pose2 end = start * Pose2::Exp({radius_mm * 1.2, 0.0, 1.2});
  const Pose2 mid = Interpolate(start, end, 0.25);
  ExpectPoseNear(mid, start * Pose2::Exp({radius_mm * 0.3, 0.0, 0.3}), 1e-9, 1e-12);
  ExpectPoseNear(Interpolate(start, end, 0.0), start);
  ExpectPoseNear(Interpolate(start, end, 1.0), end, 1e-9, 1e-12);
}

TEST(Pose2, MatrixRoundTrip) {
  const Pose2 pose(-12.5, 7.25, -2.0);
  ExpectPoseNear(Pose2::FromMatrix(pose.ToMatrix()), pose);
}

class Pose2Property : public ::testing::Test {
 protected:
  Pose2 RandomPose() {
    return Pose2(position_(rng_), position_(rng_), angle_(rng_));
  }
  std::mt19937_64 rng_{20261124};
  std::uniform_real_distribution<double> position_{-5000.0, 5000.0};
  std::uniform_real_distribution<double> angle_{-4.0, 4.0};
};

TEST_F(Pose2Property, GroupAxioms) {
  for (int i = 0; i < 2000; ++i) {
    const Pose2 a = RandomPose();
    const Pose2 b = RandomPose();
    const Pose2 c = RandomPose();
    ExpectPoseNear((a * b) * c, a * (b * c), 1e-8, 1e-12);
    ExpectPoseNear(a * a.Inverse(), Pose2::Identity(), 1e-8, 1e-12);
    ExpectPoseNear(a * Between(a, b), b, 1e-8, 1e-12);
    // Composition agrees with homogeneous matrices.
    ExpectPoseNear(a * b, Pose2::FromMatrix(a.ToMatrix() * b.ToMatrix()), 1e-8, 1e-12);
    const Eigen::Vector2d p(position_(rng_), position_(rng_));
    EXPECT_LT(((a * b) * p - a * (b * p)).norm(), 1e-8);
  }
}

TEST_F(Pose2Property, ExpLogRoundTrip) {
  for (int i = 0; i < 2000; ++i) {
    const Pose2 a = RandomPose();
    ExpectPoseNear(Pose2::Exp(a.Log()), a, 1e-8, 1e-12);
    // Small angles exercise the series branch.
    const Pose2 small(position_(rng_), position_(rng_), 1e-9 * angle_(rng_));
    ExpectPoseNear(Pose2::Exp(small.Log()), small, 1e-8, 1e-15);
  }
}

TEST_F(Pose2Property, InterpolationStaysOnGeodesic) {
  for (int i = 0; i < 500; ++i) {
    const Pose2 a = RandomPose();
    const Pose2 b = a * Pose2::Exp({position_(rng_) * 0.1, position_(rng_) * 0.01, angle_(rng_) * 0.5});
    const double t = std::uniform_real_distribution<double>(0.0, 1.0)(rng_);
    // Going t of the way, then the rest, arrives at b.
    const Pose2 mid = Interpolate(a, b, t);
    ExpectPoseNear(Interpolate(mid, b, 1.0), b, 1e-7, 1e-12);
    // The geodesic has constant body twist: equal parameter steps give equal relative motion.
    const Pose2 step1 = Between(a, Interpolate(a, b, 0.5));
    const Pose2 step2 = Between(Interpolate(a, b, 0.5), b);
    ExpectPoseNear(step1, step2, 1e-7, 1e-12);
  }
}

}  // namespace
}  // namespace mosaicloc::core
