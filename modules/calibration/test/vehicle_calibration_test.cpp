#include "mosaicloc/calibration/vehicle_calibration.hpp"
#include "mosaicloc/calibration/flat_field.hpp"

#include <cmath>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

namespace mosaicloc::calibration {
namespace {

// A straight run then a turn in place, with the truth's wheel arcs and exact camera motions
// plus registration noise.
std::vector<DriveStep> Drive(const core::Pose2& vehicle_from_camera, const core::WheelGeometry& truth, double noise_mm,
                             double noise_rad, std::uint64_t seed) {
  std::mt19937_64 random(seed);
  std::normal_distribution<double> n_mm(0.0, noise_mm), n_rad(0.0, noise_rad);
  std::vector<DriveStep> steps;
  const auto add = [&](double forward_mm, double turn_rad) {
    DriveStep step;
    const double d_l = forward_mm - 0.5 * truth.track_width_mm * turn_rad;
    const double d_r = forward_mm + 0.5 * truth.track_width_mm * turn_rad;
    step.left_wheel_rad = d_l / truth.left_wheel_radius_mm;
    step.right_wheel_rad = d_r / truth.right_wheel_radius_mm;
    const core::Pose2 vehicle_motion = turn_rad == 0.0 ? core::Pose2(forward_mm, 0.0, 0.0) : core::Pose2(0.0, 0.0, turn_rad);
    step.previous_from_current_camera = vehicle_from_camera.Inverse() * vehicle_motion * vehicle_from_camera *
                                        core::Pose2(n_mm(random), n_mm(random), n_rad(random));
    steps.push_back(step);
  };
  for (int i = 0; i < 40; ++i) add(10.0, 0.0);
  for (int i = 0; i < 100; ++i) add(0.0, 0.03);
  return steps;
}

TEST(CalibrateVehicle, RecoversMountingAndWheelsFromAStraightRunAndATurn) {
  const core::Pose2 truth(212.5, -14.0, 0.035);
  const core::WheelGeometry wheels{core::DriveKind::kDifferential, 75.4, 74.7, 507.0, 4096};
  const auto steps = Drive(truth, wheels, 0.02, 1e-4, 3);
  const VehicleCalibrationResult result = CalibrateVehicle(steps, {});
  ASSERT_TRUE(result.converged) << result.message;
  // The targets: the mounting within 0.5 mm and 0.05 degree.
  const double error[6] = {result.vehicle_from_camera.x_mm() - truth.x_mm(),
                           result.vehicle_from_camera.y_mm() - truth.y_mm(),
                           result.vehicle_from_camera.yaw_rad() - truth.yaw_rad(),
                           result.wheels.left_wheel_radius_mm - wheels.left_wheel_radius_mm,
                           result.wheels.right_wheel_radius_mm - wheels.right_wheel_radius_mm,
                           result.wheels.track_width_mm - wheels.track_width_mm};
  const double bound[6] = {0.5, 0.5, 0.05 * M_PI / 180.0, 0.1, 0.1, 0.5};
  for (int i = 0; i < 6; ++i) {
    EXPECT_LT(std::abs(error[i]), bound[i]) << "parameter " << i;
    // The stated uncertainty covers the error actually made.
    EXPECT_GT(result.sigma(i), 0.0) << "parameter " << i;
    EXPECT_LT(std::abs(error[i]), 4.0 * result.sigma(i)) << "parameter " << i;
  }
  EXPECT_NEAR(result.rms_translation_mm, 0.02 * std::sqrt(2.0), 0.01);
}

TEST(CalibrateVehicle, AStraightRunAloneIsReportedAsNotDetermining) {
  auto steps = Drive(core::Pose2(200.0, 0.0, 0.0), core::WheelGeometry{}, 0.02, 1e-4, 4);
  steps.resize(40);
  const VehicleCalibrationResult result = CalibrateVehicle(steps, {});
  EXPECT_FALSE(result.converged);
  EXPECT_NE(result.message.find("turn in place"), std::string::npos) << result.message;
}

TEST(CalibrateVehicle, LongerBaselinesComposeTheArcsOfTheirIntervals) {
  const core::Pose2 truth(212.5, -14.0, 0.035);
  const core::WheelGeometry wheels{core::DriveKind::kDifferential, 75.4, 74.7, 507.0, 4096};
  const auto single = Drive(truth, wheels, 0.0, 0.0, 5);
  // Every step also registered over three intervals, the straight run into the turn
  // included: the composed arcs must predict those motions exactly.
  std::vector<DriveStep> steps = single;
  for (std::size_t i = 0; i + 3 <= single.size(); ++i) {
    DriveStep step;
    for (std::size_t j = i; j < i + 3; ++j) {
      step.arcs.push_back({single[j].left_wheel_rad, single[j].right_wheel_rad});
      step.previous_from_current_camera = step.previous_from_current_camera * single[j].previous_from_current_camera;
    }
    steps.push_back(step);
  }
  const VehicleCalibrationResult result = CalibrateVehicle(steps, {});
  ASSERT_TRUE(result.converged) << result.message;
  EXPECT_NEAR(result.vehicle_from_camera.x_mm(), truth.x_mm(), 1e-4);
  EXPECT_NEAR(result.vehicle_from_camera.y_mm(), truth.y_mm(), 1e-4);
  EXPECT_NEAR(result.vehicle_from_camera.yaw_rad(), truth.yaw_rad(), 1e-8);
  EXPECT_NEAR(result.wheels.track_width_mm, wheels.track_width_mm, 1e-4);
  EXPECT_LT(result.rms_translation_mm, 1e-6);
}

TEST(FlatField, RecoversVignettingUnderAMovingTexture) {
  const cv::Size size(160, 120);
  cv::Mat truth(size, CV_32F);
  for (int y = 0; y < size.height; ++y) {
    for (int x = 0; x < size.width; ++x) {
      const double u = (x - 79.5) / 79.5, v = (y - 59.5) / 59.5;
      truth.at<float>(y, x) = static_cast<float>(1.0 - 0.1 * (u * u + v * v));
    }
  }
  truth /= cv::mean(truth)[0];
  FlatFieldEstimator flat(2);
  cv::RNG rng(7);
  for (int i = 0; i < 200; ++i) {
    cv::Mat floor(size, CV_32F);
    rng.fill(floor, cv::RNG::UNIFORM, 60.0, 200.0);  // a fresh patch of floor in every frame
    cv::Mat frame;
    cv::Mat(floor.mul(truth)).convertTo(frame, CV_8U);
    flat.Add(frame);
  }
  const cv::Mat gain = flat.Gain();
  double worst = 0.0;
  cv::minMaxLoc(cv::abs(gain - truth), nullptr, &worst);
  EXPECT_LT(worst, 0.01);
  // Dividing it out leaves an even image.
  cv::Mat shaded;
  cv::Mat(cv::Mat(size, CV_32F, cv::Scalar(128.0)).mul(truth)).convertTo(shaded, CV_8U);
  double lo = 0.0, hi = 0.0;
  cv::minMaxLoc(DivideByGain(shaded, gain), &lo, &hi);
  EXPECT_GE(lo, 126.0);
  EXPECT_LE(hi, 130.0);
}

}  // namespace
}  // namespace mosaicloc::calibration
