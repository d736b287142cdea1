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
