#include "mosaicloc/camera/ideal_camera.hpp"

#include <numbers>
#include <random>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::camera {
namespace {

TEST(IdealCamera, KnownValues) {
  const IdealCamera camera(IdealCameraOptions{640, 480, 0.25});
  EXPECT_DOUBLE_EQ(camera.cx(), 319.5);
  EXPECT_DOUBLE_EQ(camera.cy(), 239.5);
  EXPECT_DOUBLE_EQ(camera.width_mm(), 160.0);
  // The centre is the origin; image right is +x, image up (smaller v) is +y.
  EXPECT_TRUE(camera.PixelToCamera({319.5, 239.5}).isZero());
  EXPECT_TRUE(camera.PixelToCamera({323.5, 239.5}).isApprox(Eigen::Vector2d(1.0, 0.0)));
  EXPECT_TRUE(camera.PixelToCamera({319.5, 235.5}).isApprox(Eigen::Vector2d(0.0, 1.0)));
  // Camera 300 mm ahead of a vehicle at (1000, 0) facing +y: image right points to +y in the world.
  const core::Pose2 world_from_camera =
      core::Pose2(1000.0, 0.0, std::numbers::pi / 2) * core::Pose2(300.0, 0.0, 0.0);
  const Eigen::Vector2d world = camera.PixelToWorld({323.5, 239.5}, world_from_camera);
  EXPECT_NEAR(world.x(), 1000.0, 1e-9);
  EXPECT_NEAR(world.y(), 301.0, 1e-9);
}

TEST(IdealCamera, RoundTripAndAffineAgree) {
  const IdealCamera camera(IdealCameraOptions{752, 480, 0.2});
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-10.0, 760.0);
  std::uniform_real_distribution<double> pos(-1e5, 1e5);
  std::uniform_real_distribution<double> yaw(-4.0, 4.0);
  for (int i = 0; i < 1000; ++i) {
    const core::Pose2 world_from_camera(pos(rng), pos(rng), yaw(rng));
    const Eigen::Vector2d pixel(u(rng), u(rng));
    const Eigen::Vector2d world = camera.PixelToWorld(pixel, world_from_camera);
    EXPECT_LT((camera.WorldToPixel(world, world_from_camera) - pixel).norm(), 1e-8);
    const Eigen::Matrix<double, 2, 3> affine = camera.PixelToWorldAffine(world_from_camera);
    EXPECT_LT((affine * pixel.homogeneous() - world).norm(), 1e-8);
  }
}

TEST(IdealCamera, FootprintLength) {
  const IdealCamera camera(IdealCameraOptions{640, 480, 0.25});
  EXPECT_DOUBLE_EQ(camera.FootprintLengthAlong(0.0), 160.0);
  EXPECT_NEAR(camera.FootprintLengthAlong(std::numbers::pi / 2), 120.0, 1e-9);
  // Diagonally the height limits first: 120 / sin(45 deg).
  EXPECT_NEAR(camera.FootprintLengthAlong(std::numbers::pi / 4), 120.0 * std::sqrt(2.0), 1e-9);
}

TEST(IdealCamera, RejectsBadOptions) {
  EXPECT_THROW(IdealCamera(IdealCameraOptions{640, 480, 0.0}), core::Error);
  EXPECT_THROW(IdealCamera(IdealCameraOptions{0, 480, 0.25}), core::Error);
  const IdealCamera camera(IdealCameraOptions{});
  EXPECT_TRUE(camera.Contains({0.0, 0.0}));
  EXPECT_FALSE(camera.Contains({639.6, 0.0}));
}

}  // namespace
}  // namespace mosaicloc::camera
