#include "mosaicloc/sim/stance.hpp"

#include <cmath>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

#include "mosaicloc/camera/ideal_camera.hpp"

namespace mosaicloc::sim {
namespace {

const camera::IdealCamera kCamera(camera::IdealCameraOptions{640, 480, 0.25});

CameraPlacement Placement(const CameraPlacementOptions& options) {
  return CameraPlacement(options, kCamera.mm_per_px(), kCamera.cx(), kCamera.cy());
}

CameraPlacementOptions Mounted() {
  CameraPlacementOptions options;
  options.vehicle_from_camera = core::Pose2(200.0, 30.0, 0.3);
  return options;
}

TEST(CameraPlacement, StraightDownFromTheCalibratedHeightIsTheIdealCamera) {
  const CameraPlacement placement = Placement(Mounted());
  EXPECT_TRUE(placement.straight_down());
  const core::Pose2 world_from_vehicle(1234.0, -567.0, 2.1);
  const CameraView view = placement.At(world_from_vehicle, Eigen::Vector2d(1.0, 0.5), 12.0);
  const core::Pose2 world_from_camera = world_from_vehicle * Mounted().vehicle_from_camera;
  for (const Eigen::Vector2d& pixel : {Eigen::Vector2d(0, 0), Eigen::Vector2d(639, 479), Eigen::Vector2d(100.5, 300.25)}) {
    EXPECT_LT((placement.PixelToWorld(view, pixel) - kCamera.PixelToWorld(pixel, world_from_camera)).norm(), 1e-9);
  }
  const dataset::CameraTruth truth = placement.Truth(view, world_from_vehicle);
  EXPECT_NEAR(truth.height_mm, 200.0, 1e-9);
  EXPECT_NEAR(truth.tilt_x_rad, 0.0, 1e-12);
  EXPECT_NEAR(truth.tilt_y_rad, 0.0, 1e-12);
  EXPECT_LT(truth.centre_offset_mm.norm(), 1e-9);
}

TEST(CameraPlacement, AHigherCameraSeesMoreFloorAndItsHeightDrifts) {
  CameraPlacementOptions options = Mounted();
  options.height_offset_mm = 2.0;
  options.height_drift_mm_per_min = 1.5;
  const CameraPlacement placement = Placement(options);
  EXPECT_FALSE(placement.straight_down());
  const core::Pose2 world_from_vehicle(10.0, 20.0, 0.0);
  const CameraView view = placement.At(world_from_vehicle, Eigen::Vector2d::Zero(), 120.0);
  EXPECT_NEAR(placement.Truth(view, world_from_vehicle).height_mm, 205.0, 1e-9);
  // A pixel 320 px from the centre looks 80 mm out at 200 mm, 82 mm at 205 mm.
  const Eigen::Vector2d centre = placement.PixelToWorld(view, Eigen::Vector2d(kCamera.cx(), kCamera.cy()));
  const Eigen::Vector2d edge = placement.PixelToWorld(view, Eigen::Vector2d(kCamera.cx() + 320.0, kCamera.cy()));
  EXPECT_NEAR((edge - centre).norm(), 80.0 * 205.0 / 200.0, 1e-9);
}

// Braking and turning tilt the body about the pivot: the image centre moves on the floor by
// the pivot's height times the angle, and the camera sees the tilt.
TEST(CameraPlacement, AccelerationPitchesAndTurningRollsAboutThePivot) {
  CameraPlacementOptions options = Mounted();
  options.vehicle_from_camera = core::Pose2(200.0, 0.0, 0.0);
  options.suspension.pitch_deg_per_mps2 = 0.5;
  options.suspension.roll_deg_per_mps2 = 0.3;
  options.suspension.pivot_height_mm = 120.0;
  const CameraPlacement placement = Placement(options);
  const core::Pose2 world_from_vehicle(0.0, 0.0, 0.7);
  const double pitch = 0.5 * std::numbers::pi / 180.0;
  const double roll = 2 * 0.3 * std::numbers::pi / 180.0;

  // Accelerating: the nose comes up, the body turns back about the pivot.
  const dataset::CameraTruth accelerating =
      placement.Truth(placement.At(world_from_vehicle, Eigen::Vector2d(1.0, 0.0), 0.0), world_from_vehicle);
  EXPECT_NEAR(accelerating.tilt_y_rad, -pitch, 1e-9);
  EXPECT_NEAR(accelerating.tilt_x_rad, 0.0, 1e-12);
  // To first order; the mounting's 200 mm lever adds 200 pitch^2 = 0.015 mm.
  EXPECT_NEAR(accelerating.centre_offset_mm.x(), 120.0 * pitch, 0.02);
  EXPECT_NEAR(accelerating.centre_offset_mm.y(), 0.0, 1e-9);
  // A left turn at 2 m/s^2: the left side rises.
  const dataset::CameraTruth turning =
      placement.Truth(placement.At(world_from_vehicle, Eigen::Vector2d(0.0, 2.0), 0.0), world_from_vehicle);
  EXPECT_NEAR(turning.tilt_x_rad, roll, 1e-9);
  EXPECT_NEAR(turning.centre_offset_mm.y(), 120.0 * roll, 0.002);
  // The height over the floor changes only with the cosine of the angle.
  EXPECT_NEAR(turning.height_mm, 200.0, 0.01);
}

TEST(FloorShape, HasTheRequestedRoughnessAndRaysLandOnIt) {
  const FloorShape shape(2.0, 1.0, 7);
  ASSERT_FALSE(shape.flat());
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> site(-20000.0, 20000.0);
  double sum_sq = 0.0;
  constexpr int kSamples = 20000;
  for (int i = 0; i < kSamples; ++i) {
    const double h = shape.HeightMm(Eigen::Vector2d(site(rng), site(rng)));
    sum_sq += h * h;
  }
  EXPECT_NEAR(std::sqrt(sum_sq / kSamples), 2.0, 0.3);
  // A slanted ray from 200 mm up meets the floor where the floor is.
  const Eigen::Vector3d origin(150.0, -40.0, 200.0);
  const Eigen::Vector3d direction = Eigen::Vector3d(0.3, -0.2, -1.0).normalized();
  const Eigen::Vector2d hit = shape.Intersect(origin, direction);
  const double tau = (hit.x() - origin.x()) / direction.x();
  EXPECT_NEAR(origin.z() + tau * direction.z(), shape.HeightMm(hit), 1e-9);
  EXPECT_NEAR(origin.y() + tau * direction.y(), hit.y(), 1e-9);
  // The gradient is the height's derivative.
  const Eigen::Vector2d p(321.0, 654.0);
  const double step = 1e-3;
  EXPECT_NEAR(shape.Gradient(p).x(),
              (shape.HeightMm(p + Eigen::Vector2d(step, 0)) - shape.HeightMm(p - Eigen::Vector2d(step, 0))) / (2 * step),
              1e-8);
  Eigen::Vector2d gradient;
  EXPECT_NEAR(shape.HeightAndGradient(p, &gradient), shape.HeightMm(p), 1e-12);
  EXPECT_NEAR((gradient - shape.Gradient(p)).norm(), 0.0, 1e-15);
  EXPECT_TRUE(FloorShape(0.0, 2.0, 7).flat());
}

// On an uneven floor the vehicle stands on its wheels and caster: the camera's height over
// the floor it sees changes with the floor, and its tilt against that floor stays small.
TEST(CameraPlacement, AnUnevenFloorMovesTheCameraThroughTheWheels) {
  CameraPlacementOptions options = Mounted();
  options.unevenness_mm = 1.0;
  options.unevenness_wavelength_m = 1.0;
  const CameraPlacement placement = Placement(options);
  double min_height = 1e9, max_height = -1e9, max_tilt = 0.0;
  for (int i = 0; i < 400; ++i) {
    const core::Pose2 world_from_vehicle(10.0 * i, 3.0 * i, 0.01 * i);
    const dataset::CameraTruth truth =
        placement.Truth(placement.At(world_from_vehicle, Eigen::Vector2d::Zero(), 0.0), world_from_vehicle);
    min_height = std::min(min_height, truth.height_mm);
    max_height = std::max(max_height, truth.height_mm);
    max_tilt = std::max({max_tilt, std::abs(truth.tilt_x_rad), std::abs(truth.tilt_y_rad)});
  }
  EXPECT_GT(max_height - min_height, 0.2);
  EXPECT_LT(max_height - min_height, 10.0);
  EXPECT_GT(max_tilt, 1e-5);
  EXPECT_LT(max_tilt, 0.01);
}

TEST(CameraPlacement, ResidualDistortionPushesTheCornersOut) {
  CameraPlacementOptions options = Mounted();
  options.residual_k1 = 0.01;
  const CameraPlacement placement = Placement(options);
  const CameraPlacement ideal = Placement(Mounted());
  const core::Pose2 world_from_vehicle;
  const CameraView view = placement.At(world_from_vehicle, Eigen::Vector2d::Zero(), 0.0);
  const Eigen::Vector2d corner(0.0, 0.0);
  const Eigen::Vector2d centre(kCamera.cx(), kCamera.cy());
  const double r_ideal = (ideal.PixelToWorld(view, corner) - ideal.PixelToWorld(view, centre)).norm();
  const double r_real = (placement.PixelToWorld(view, corner) - placement.PixelToWorld(view, centre)).norm();
  const double normalized = r_ideal / 200.0;
  EXPECT_NEAR(r_real / r_ideal, 1.0 + 0.01 * normalized * normalized, 1e-9);
}

}  // namespace
}  // namespace mosaicloc::sim
