#include "mosaicloc/calibration/vehicle_drive.hpp"

#include <cmath>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/sim/calibration_drive.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::calibration {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

std::string ErrorOf(const std::function<void()>& run) {
  try {
    run();
  } catch (const core::Error& e) {
    EXPECT_EQ(e.kind(), core::ErrorKind::kInvalidInput) << e.what();
    return e.what();
  }
  ADD_FAILURE() << "no error";
  return "";
}

TEST(VehicleDrive, ASimulatedDriveGivesTheTrueMountingAndWheels) {
  test::ScratchDir scratch;
  // A shorter drive than `calibrate simulate-drive` writes, and fewer baselines: enough to
  // determine all six values, quick under the sanitizers.
  sim::CalibrationDriveOptions drive;
  drive.straight_mm = 200.0;
  drive.turn_rad = 1.5;
  sim::WriteCalibrationDrive(drive, scratch / "drive", false);
  VehicleDriveOptions options;
  options.baselines = 4;
  int calls = 0;
  double last = 0.0;
  const VehicleDriveResult result = CalibrateVehicleFromDrive(scratch / "drive", options, [&](double fraction) {
    ++calls;
    EXPECT_GE(fraction, last);
    last = fraction;
  });
  ASSERT_TRUE(result.calibration.converged) << result.calibration.message;
  EXPECT_EQ(calls, result.frames);
  EXPECT_DOUBLE_EQ(last, 1.0);
  EXPECT_EQ(result.not_registered, 0);
  EXPECT_EQ(result.consecutive_steps, result.frames - 1);
  EXPECT_GT(result.steps, result.consecutive_steps);
  ASSERT_TRUE(result.truth.has_value());
  const VehicleParameters& truth = *result.truth;
  EXPECT_NEAR(truth[0], drive.vehicle_from_camera.x_mm(), 1e-9);
  EXPECT_NEAR(truth[5], drive.vehicle.track_width_mm, 1e-9);
  const core::Pose2& x = result.calibration.vehicle_from_camera;
  EXPECT_NEAR(x.x_mm(), truth[0], 1.0);
  EXPECT_NEAR(x.y_mm(), truth[1], 1.0);
  EXPECT_NEAR(x.yaw_rad(), truth[2], 0.2 * M_PI / 180.0);
  EXPECT_NEAR(result.calibration.wheels.left_wheel_radius_mm, truth[3], 0.2);
  EXPECT_NEAR(result.calibration.wheels.right_wheel_radius_mm, truth[4], 0.2);
  EXPECT_NEAR(result.calibration.wheels.track_width_mm, truth[5], 2.0);
}

// A tug: its drive wheel's radius, the wheelbase and the steering encoder's zero from a
// straight run and a pivot with the steered wheel across, within the targets (0.5 mm, 0.05
// degree) and the truth within four of the stated sigmas.
TEST(VehicleDrive, ASimulatedTricycleDriveGivesItsWheelbaseAndSteeringOffset) {
  test::ScratchDir scratch;
  sim::CalibrationDriveOptions drive = sim::CalibrationDriveFor(core::DriveKind::kTricycle);
  drive.turn_rad = 1.5;  // quicker under the sanitizers; the straight run stays as long
  sim::WriteCalibrationDrive(drive, scratch / "drive", false);
  VehicleDriveOptions options;
  options.baselines = 3;
  const VehicleDriveResult result = CalibrateVehicleFromDrive(scratch / "drive", options);
  ASSERT_TRUE(result.calibration.converged) << result.calibration.message;
  EXPECT_EQ(result.kind, core::DriveKind::kTricycle);
  EXPECT_EQ(result.not_registered, 0);
  ASSERT_TRUE(result.truth.has_value());
  const VehicleParameters& truth = *result.truth;
  EXPECT_NEAR(truth[4], drive.vehicle.wheelbase_mm, 1e-9);
  EXPECT_NEAR(truth[5], drive.vehicle.steering_offset_deg * M_PI / 180.0, 1e-9);
  const double bound[6] = {0.5, 0.5, 0.05 * M_PI / 180.0, 0.1, 0.5, 0.05 * M_PI / 180.0};
  for (std::size_t i = 0; i < 6; ++i) {
    const double error = result.value[i] - truth[i];
    EXPECT_LT(std::abs(error), bound[i]) << ParameterNamesOf(result.kind).labels[i] << " sigma " << result.sigma[i] << " error " << error;
    EXPECT_LT(std::abs(error), 4.0 * result.sigma[i]) << ParameterNamesOf(result.kind).labels[i];
  }
  EXPECT_NEAR(result.calibration.wheels.steering_offset_deg * M_PI / 180.0, result.value[5], 1e-12);
}

TEST(VehicleDrive, ADriveWithoutEncodersIsBadInputNamingIt) {
  test::ScratchDir scratch;
  dataset::DatasetInfo info;
  dataset::DatasetWriter writer(scratch / "empty", info, false);
  writer.AddFrame(core::Timestamp::FromNanoseconds(1000000), cv::Mat(info.camera.height_px, info.camera.width_px,
                                                                        CV_8UC1, cv::Scalar(100)));
  writer.Commit();
  const std::string error = ErrorOf([&] { CalibrateVehicleFromDrive(scratch / "empty", {}); });
  EXPECT_THAT(error, HasSubstr("empty"));
  EXPECT_THAT(error, HasSubstr("no encoder samples"));
  VehicleDriveOptions bad;
  bad.min_overlap = 1.5;
  EXPECT_THAT(ErrorOf([&] { CalibrateVehicleFromDrive(scratch / "empty", bad); }), HasSubstr("min_overlap"));
}

TEST(VehicleCalibrationFile, RoundTripsExactly) {
  test::ScratchDir scratch;
  VehicleCalibrationFile written;
  written.vehicle_from_camera = core::Pose2(212.51234567891234, -14.000000001, 0.0351);
  written.wheels = {core::DriveKind::kDifferential, 75.4000000001, 74.7, 507.03, 4096};
  written.sigma = {0.01, 0.02, 1e-5, 0.003, 0.004, 0.05};
  WriteVehicleCalibration(scratch / "vehicle.yaml", written, "a comment\non two lines");
  const std::string text = test::ReadFile(scratch / "vehicle.yaml");
  EXPECT_EQ(text.rfind("# a comment\n# on two lines\n", 0), 0u) << text;
  const VehicleCalibrationFile read = ReadVehicleCalibration(scratch / "vehicle.yaml");
  EXPECT_EQ(read.vehicle_from_camera.x_mm(), written.vehicle_from_camera.x_mm());
  EXPECT_EQ(read.vehicle_from_camera.y_mm(), written.vehicle_from_camera.y_mm());
  EXPECT_EQ(read.vehicle_from_camera.yaw_rad(), written.vehicle_from_camera.yaw_rad());
  EXPECT_EQ(read.wheels.left_wheel_radius_mm, written.wheels.left_wheel_radius_mm);
  EXPECT_EQ(read.wheels.track_width_mm, written.wheels.track_width_mm);
  EXPECT_EQ(read.sigma, written.sigma);
}

// A tricycle's file names its kind and its three, the steering offset and its sigma in degrees.
TEST(VehicleCalibrationFile, RoundTripsATricycle) {
  test::ScratchDir scratch;
  VehicleCalibrationFile written;
  written.vehicle_from_camera = core::Pose2(212.5, -14.0, 0.035);
  written.wheels.kind = core::DriveKind::kTricycle;
  written.wheels.drive_wheel_radius_mm = 100.35;
  written.wheels.wheelbase_mm = 1206.5;
  written.wheels.steering_offset_deg = 0.42;
  written.sigma = {0.02, 0.25, 6e-5, 0.004, 0.1, 2.2e-4};
  WriteVehicleCalibration(scratch / "vehicle.yaml", written, "a tug");
  const std::string text = test::ReadFile(scratch / "vehicle.yaml");
  EXPECT_THAT(text, HasSubstr("kind: tricycle"));
  EXPECT_THAT(text, HasSubstr("steering_offset_deg: 0.41999999999999998"));
  EXPECT_THAT(text, Not(HasSubstr("track_width_mm")));
  const VehicleCalibrationFile read = ReadVehicleCalibration(scratch / "vehicle.yaml");
  EXPECT_EQ(read.wheels.kind, core::DriveKind::kTricycle);
  EXPECT_EQ(read.wheels.drive_wheel_radius_mm, 100.35);
  EXPECT_EQ(read.wheels.wheelbase_mm, 1206.5);
  EXPECT_EQ(read.wheels.steering_offset_deg, 0.42);
  for (std::size_t i = 0; i < 6; ++i) EXPECT_NEAR(read.sigma[i], written.sigma[i], 1e-15 * written.sigma[i]) << i;
  // A differential drive's key in a tricycle's file is named.
  std::string mixed = text;
  mixed.replace(mixed.find("wheelbase_mm:"), std::string("wheelbase_mm:").size(), "track_width_mm:");
  test::WriteFile(scratch / "vehicle.yaml", mixed);
  const std::string error = ErrorOf([&] { ReadVehicleCalibration(scratch / "vehicle.yaml"); });
  EXPECT_THAT(error, HasSubstr("wheelbase_mm: missing required key"));
  EXPECT_THAT(error, HasSubstr("track_width_mm: unknown key"));
}

TEST(VehicleCalibrationFile, BadInputNamesTheFileLineAndKey) {
  test::ScratchDir scratch;
  const auto file = scratch / "vehicle.yaml";
  const std::string good =
      "format_version: 1\n"
      "vehicle_from_camera: {x_mm: 200, y_mm: 0, yaw_rad: 0}\n"
      "vehicle_from_camera_sigma: {x_mm: 0.1, y_mm: 0.1, yaw_rad: 0.001}\n"
      "left_wheel_radius_mm: 75\n"
      "right_wheel_radius_mm: 75\n"
      "track_width_mm: 500\n"
      "wheel_sigma: {left_wheel_radius_mm: 0.1, right_wheel_radius_mm: 0.1, track_width_mm: 1}\n";
  test::WriteFile(file, good);
  EXPECT_EQ(ReadVehicleCalibration(file).wheels.track_width_mm, 500.0);
  const auto replaced = [&](const std::string& from, const std::string& to) {
    std::string text = good;
    text.replace(text.find(from), from.size(), to);
    test::WriteFile(file, text);
    return ErrorOf([&] { ReadVehicleCalibration(file); });
  };
  EXPECT_THAT(replaced("track_width_mm: 500", "track_width_mm: -500"),
              HasSubstr("vehicle.yaml:6: track_width_mm: must be > 0 mm"));
  EXPECT_THAT(replaced("yaw_rad: 0}", "yaw_rad: 7}"), HasSubstr("vehicle.yaml:2: vehicle_from_camera.yaw_rad"));
  EXPECT_THAT(replaced("right_wheel_radius_mm: 75\n", ""), HasSubstr("right_wheel_radius_mm: missing required key"));
  EXPECT_THAT(replaced("format_version: 1", "format_version: 1\nextra: 3"), HasSubstr("extra: unknown key"));
}

}  // namespace
}  // namespace mosaicloc::calibration
