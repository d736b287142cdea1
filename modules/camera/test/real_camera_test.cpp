#include "mosaicloc/camera/real_camera.hpp"

#include <random>

#include <gtest/gtest.h>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/error.hpp"

namespace mosaicloc::camera {
namespace {

TEST(RealCamera, StraightDownWithoutDistortionIsAnIdealCamera) {
  // A pinhole looking straight down at a plane images it with a uniform scale h / f.
  RealCameraOptions options;
  options.fx_px = options.fy_px = 800.0;
  options.height_mm = 200.0;
  const RealCamera real(options);
  const IdealCamera ideal(IdealCameraOptions{640, 480, real.NadirMmPerPx()});
  EXPECT_DOUBLE_EQ(real.NadirMmPerPx(), 0.25);
  for (const Eigen::Vector2d& pixel : {Eigen::Vector2d(0, 0), Eigen::Vector2d(639, 479), Eigen::Vector2d(100.25, 400.5)}) {
    const auto floor = real.PixelToFloor(pixel);
    ASSERT_TRUE(floor.has_value());
    EXPECT_LT((*floor - ideal.PixelToCamera(pixel)).norm(), 1e-9);
  }
}

TEST(RealCamera, DistortionKnownValue) {
  RealCameraOptions options;
  options.k1 = -0.2;
  options.k2 = 0.05;
  const RealCamera camera(options);
  // Normalized point (0.5, 0): r^2 = 0.25, d = 1 - 0.05 + 0.003125.
  const Eigen::Vector2d pixel = camera.Distort({0.5, 0.0});
  EXPECT_NEAR(pixel.x(), 319.5 + 800.0 * 0.5 * 0.953125, 1e-9);
  EXPECT_NEAR(pixel.y(), 239.5, 1e-12);
}

TEST(RealCamera, RandomizedRoundTripWithTiltAndDistortion) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> tilt(-0.08, 0.08);
  std::uniform_real_distribution<double> k(-0.3, 0.1);
  std::uniform_real_distribution<double> u(0.0, 639.0);
  std::uniform_real_distribution<double> v(0.0, 479.0);
  for (int trial = 0; trial < 50; ++trial) {
    RealCameraOptions options;
    options.k1 = k(rng);
    options.k2 = 0.1 * k(rng);
    options.tilt_x_rad = tilt(rng);
    options.tilt_y_rad = tilt(rng);
    options.height_mm = 150.0 + 100.0 * std::abs(tilt(rng));
    const RealCamera camera(options);
    for (int i = 0; i < 100; ++i) {
      const Eigen::Vector2d pixel(u(rng), v(rng));
      const auto floor = camera.PixelToFloor(pixel);
      ASSERT_TRUE(floor.has_value());
      const auto back = camera.FloorToPixel(*floor);
      ASSERT_TRUE(back.has_value());
      EXPECT_LT((*back - pixel).norm(), 1e-7);
    }
  }
}

TEST(RealCamera, TiltShiftsTheNadir) {
  RealCameraOptions options;
  options.tilt_x_rad = 0.05;
  const RealCamera camera(options);
  // The floor point under the optical centre no longer projects to the principal point.
  const auto nadir = camera.FloorToPixel({0.0, 0.0});
  ASSERT_TRUE(nadir.has_value());
  EXPECT_NEAR(nadir->x(), 319.5, 1e-9);
  EXPECT_NEAR(nadir->y(), 239.5 + 800.0 * std::tan(-0.05), 1e-6);
}

TEST(RealCamera, RejectsBadOptions) {
  RealCameraOptions options;
  options.height_mm = -1.0;
  EXPECT_THROW(RealCamera{options}, core::Error);
  options = RealCameraOptions{};
  options.tilt_y_rad = 1.0;
  EXPECT_THROW(RealCamera{options}, core::Error);
}

}  // namespace
}  // namespace mosaicloc::camera
