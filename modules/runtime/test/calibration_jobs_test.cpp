#include "mosaicloc/runtime/calibration_jobs.hpp"

#include <numbers>

#include <gtest/gtest.h>

namespace mosaicloc::runtime {
namespace {

constexpr double kPi = std::numbers::pi;

calibration::VehicleDriveResult TricycleDrive() {
  calibration::VehicleDriveResult drive;
  drive.kind = core::DriveKind::kTricycle;
  drive.frames = 146;
  drive.steps = 400;
  drive.consecutive_steps = 144;
  drive.not_registered = 1;
  drive.calibration.rms_rotation_rad = kPi / 1800.0;
  drive.value = {120.0, -4.0, kPi / 2.0, 75.2, 910.0, kPi / 180.0};
  drive.sigma = {0.01, 0.02, kPi / 18000.0, 0.001, 0.5, kPi / 3600.0};
  return drive;
}

TEST(CalibrationJobs, AVehicleCalibrationIsShownInItsKindsKeysAndUnits) {
  calibration::VehicleDriveResult drive = TricycleDrive();
  nlohmann::json json = VehicleCalibrationJson(drive, {});
  EXPECT_EQ(json["kind"], "tricycle");
  EXPECT_EQ(json["consecutive_steps"], 144);
  EXPECT_EQ(json["not_registered"], 1);
  EXPECT_NEAR(json["rms_rotation_deg"].get<double>(), 0.1, 1e-12);
  EXPECT_NEAR(json["yaw_deg"]["value"].get<double>(), 90.0, 1e-12);
  EXPECT_NEAR(json["yaw_deg"]["sigma"].get<double>(), 0.01, 1e-12);
  EXPECT_NEAR(json["steering_offset_deg"]["value"].get<double>(), 1.0, 1e-12);
  EXPECT_NEAR(json["wheelbase_mm"]["sigma"].get<double>(), 0.5, 1e-12);
  EXPECT_FALSE(json.contains("track_width_mm"));
  EXPECT_FALSE(json["x_mm"].contains("truth"));  // a recorded drive knows no truth
  EXPECT_FALSE(json.contains("out"));

  drive.truth = drive.value;
  (*drive.truth)[0] = 119.5;
  (*drive.truth)[2] = kPi / 2.0 + kPi / 1800.0;
  json = VehicleCalibrationJson(drive, "vehicle.yaml");
  EXPECT_EQ(json["out"], "vehicle.yaml");
  EXPECT_NEAR(json["x_mm"]["truth"].get<double>(), 119.5, 1e-12);
  EXPECT_NEAR(json["x_mm"]["error"].get<double>(), 0.5, 1e-12);
  EXPECT_NEAR(json["yaw_deg"]["error"].get<double>(), -0.1, 1e-12);
  EXPECT_NEAR(json["wheelbase_mm"]["error"].get<double>(), 0.0, 1e-12);
}

TEST(CalibrationJobs, GroundAndVerificationAreShownInMillimetresDegreesAndPercent) {
  calibration::GroundResult ground;
  ground.calibration.ideal.mm_per_px = 0.25;
  ground.calibration.ideal.width_px = 560;
  ground.calibration.ideal.height_px = 400;
  ground.coverage = 0.97;
  ground.views.push_back({"floor-01.png", 0.004, 0.011, -0.0002});
  const nlohmann::json json = GroundJson(ground, "ground.yaml");
  EXPECT_EQ(json["ground"], "ground.yaml");
  EXPECT_EQ(json["width_px"], 560);
  EXPECT_DOUBLE_EQ(json["coverage"].get<double>(), 0.97);
  ASSERT_EQ(json["images"].size(), 1u);
  EXPECT_EQ(json["images"][0]["image"], "floor-01.png");
  EXPECT_NEAR(json["images"][0]["scale_error_percent"].get<double>(), -0.02, 1e-12);
  EXPECT_TRUE(json.contains("height_mm"));
  EXPECT_TRUE(json.contains("tilt_deg"));

  calibration::RectificationCheck check;
  check.images.push_back({"/data/raw/floor-05.png", {0.0003, 0.002, 0.005}});
  check.worst_scale_error = 0.0003;
  const nlohmann::json verified = RectificationCheckJson(check);
  EXPECT_EQ(verified["images"][0]["image"], "floor-05.png");  // the name, not the path
  EXPECT_NEAR(verified["images"][0]["scale_error_percent"].get<double>(), 0.03, 1e-12);
  EXPECT_NEAR(verified["worst_scale_error_percent"].get<double>(), 0.03, 1e-12);
}

TEST(CalibrationJobs, IntrinsicsListEveryImageUsedOrWhyNot) {
  calibration::ImagesIntrinsics calibrated;
  calibrated.width_px = 640;
  calibrated.height_px = 480;
  calibrated.result.visp.intrinsics.fx_px = 812.0;
  calibrated.result.opencv.intrinsics.kud = -0.14;
  calibration::ViewReport used;
  used.name = "board-01.png";
  used.used = true;
  used.visp_rms_px = 0.013;
  calibration::ViewReport rejected;
  rejected.name = "board-02.png";
  rejected.rejected_because = "no board found";
  calibrated.result.views = {used, rejected};
  const nlohmann::json json =
      IntrinsicsJson(calibrated, camera::ParseBoardSpec("chessboard:9x6:20mm"), "camera.xml");
  EXPECT_EQ(json["camera_xml"], "camera.xml");
  EXPECT_EQ(json["board"], "chessboard:9x6:20mm");
  EXPECT_DOUBLE_EQ(json["visp"]["fx_px"].get<double>(), 812.0);
  EXPECT_DOUBLE_EQ(json["opencv"]["kud"].get<double>(), -0.14);
  ASSERT_EQ(json["images"].size(), 2u);
  EXPECT_EQ(json["images"][0]["used"], true);
  EXPECT_DOUBLE_EQ(json["images"][0]["visp_rms_px"].get<double>(), 0.013);
  EXPECT_EQ(json["images"][1]["used"], false);
  EXPECT_EQ(json["images"][1]["rejected_because"], "no board found");
  EXPECT_FALSE(json["images"][1].contains("visp_rms_px"));
}

}  // namespace
}  // namespace mosaicloc::runtime
