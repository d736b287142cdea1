#include "mosaicloc/calibration/vehicle_calibration.hpp"
#include "mosaicloc/calibration/flat_field.hpp"

#include <cmath>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

namespace mosaicloc::calibration {
namespace {

// A straight run then a turn in place, with the truth's wheel arcs and exact camera motions
// plus registration noise. A tricycle drives straight with its steered wheel ahead and pivots
// with it across; its steering encoder reads the angle less the true offset.
std::vector<DriveStep> Drive(const core::Pose2& vehicle_from_camera, const core::WheelGeometry& truth, double noise_mm,
                             double noise_rad, std::uint64_t seed) {
  std::mt19937_64 random(seed);
  std::normal_distribution<double> n_mm(0.0, noise_mm), n_rad(0.0, noise_rad);
  std::vector<DriveStep> steps;
  const auto add = [&](double forward_mm, double turn_rad) {
    WheelTurn turn;
    if (truth.kind == core::DriveKind::kTricycle) {
      turn.drive_wheel_rad = (forward_mm + truth.wheelbase_mm * turn_rad) / truth.drive_wheel_radius_mm;
      turn.steering_rad = (turn_rad == 0.0 ? 0.0 : M_PI / 2.0) - truth.steering_offset_deg * M_PI / 180.0;
    } else {
      turn.left_wheel_rad = (forward_mm - 0.5 * truth.track_width_mm * turn_rad) / truth.left_wheel_radius_mm;
      turn.right_wheel_rad = (forward_mm + 0.5 * truth.track_width_mm * turn_rad) / truth.right_wheel_radius_mm;
    }
    DriveStep step;
    step.arcs = {turn};
    const core::Pose2 vehicle_motion = turn_rad == 0.0 ? core::Pose2(forward_mm, 0.0, 0.0) : core::Pose2(0.0, 0.0, turn_rad);
    step.previous_from_current_camera = vehicle_from_camera.Inverse() * vehicle_motion * vehicle_from_camera *
                                        core::Pose2(n_mm(random), n_mm(random), n_rad(random));
    steps.push_back(step);
  };
  for (int i = 0; i < 40; ++i) add(10.0, 0.0);
  for (int i = 0; i < 100; ++i) add(0.0, 0.03);
  return steps;
}

core::WheelGeometry Tricycle(double drive_radius_mm, double wheelbase_mm, double steering_offset_deg) {
  core::WheelGeometry wheels;
  wheels.kind = core::DriveKind::kTricycle;
  wheels.drive_wheel_radius_mm = drive_radius_mm;
  wheels.wheelbase_mm = wheelbase_mm;
  wheels.steering_offset_deg = steering_offset_deg;
  return wheels;
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
      step.arcs.push_back(single[j].arcs.front());
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

// A tug's drive wheel, wheelbase and steering zero a little off their nominal values: the
// targets are the steering offset within 0.05 degree and the wheelbase within 0.5 mm. The
// offset shows only as the heading the straight run gains (a pivot cannot tell it from a
// sideways lever arm), so the drive registers each frame also to the one ten frames back, as
// a calibration drive's longer baselines do.
TEST(CalibrateVehicle, RecoversATricyclesWheelbaseAndSteeringOffset) {
  const core::Pose2 truth(212.5, -14.0, 0.035);
  const core::WheelGeometry wheels = Tricycle(100.35, 1206.5, 0.42);
  const auto exact = Drive(truth, wheels, 0.0, 0.0, 6);
  std::mt19937_64 random(7);
  std::normal_distribution<double> n_mm(0.0, 0.02), n_rad(0.0, 1e-4);
  const auto noisy = [&](const core::Pose2& motion) {
    return motion * core::Pose2(n_mm(random), n_mm(random), n_rad(random));
  };
  std::vector<DriveStep> steps;
  for (std::size_t i = 0; i < exact.size(); ++i) {
    steps.push_back({exact[i].arcs, noisy(exact[i].previous_from_current_camera)});
    if (i < 10) continue;
    DriveStep longer;
    core::Pose2 motion;
    for (std::size_t j = i - 9; j <= i; ++j) {
      longer.arcs.push_back(exact[j].arcs.front());
      motion = motion * exact[j].previous_from_current_camera;
    }
    longer.previous_from_current_camera = noisy(motion);
    steps.push_back(longer);
  }
  VehicleCalibrationOptions options;
  options.initial_wheels = Tricycle(100.0, 1200.0, 0.0);
  options.independent_steps = static_cast<int>(exact.size());
  const VehicleCalibrationResult result = CalibrateVehicle(steps, options);
  ASSERT_TRUE(result.converged) << result.message;
  EXPECT_EQ(result.wheels.kind, core::DriveKind::kTricycle);
  const double error[6] = {result.vehicle_from_camera.x_mm() - truth.x_mm(),
                           result.vehicle_from_camera.y_mm() - truth.y_mm(),
                           result.vehicle_from_camera.yaw_rad() - truth.yaw_rad(),
                           result.wheels.drive_wheel_radius_mm - wheels.drive_wheel_radius_mm,
                           result.wheels.wheelbase_mm - wheels.wheelbase_mm,
                           (result.wheels.steering_offset_deg - wheels.steering_offset_deg) * M_PI / 180.0};
  const double bound[6] = {0.5, 0.5, 0.05 * M_PI / 180.0, 0.1, 0.5, 0.05 * M_PI / 180.0};
  for (int i = 0; i < 6; ++i) {
    EXPECT_LT(std::abs(error[i]), bound[i]) << "parameter " << i << ", sigma " << result.sigma(i);
    EXPECT_GT(result.sigma(i), 0.0) << "parameter " << i;
    EXPECT_LT(std::abs(error[i]), 4.0 * result.sigma(i)) << "parameter " << i;
  }
  // A straight run alone says nothing of the wheelbase.
  auto straight = exact;
  straight.resize(40);
  const VehicleCalibrationResult refused = CalibrateVehicle(straight, options);
  EXPECT_FALSE(refused.converged);
  EXPECT_NE(refused.message.find("pivoting about the fixed axle"), std::string::npos) << refused.message;
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
