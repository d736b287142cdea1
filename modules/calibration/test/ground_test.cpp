#include "mosaicloc/calibration/ground.hpp"

#include <cmath>
#include <cstdio>

#include <Eigen/Geometry>

#include <gtest/gtest.h>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/sim/raw_imaging.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::calibration {
namespace {

Intrinsics IntrinsicsOf(const camera::RealCameraOptions& truth) {
  return {truth.width_px, truth.height_px, truth.fx_px, truth.fy_px, truth.cx_px, truth.cy_px, truth.k1, 0.0};
}

// The board lying on the floor around the nadir, turned and shifted.
std::vector<BoardView> FloorViews(const camera::RealCamera& camera, const camera::BoardSpec& board,
                                  const std::vector<core::Pose2>& placements) {
  std::vector<BoardView> views;
  for (std::size_t i = 0; i < placements.size(); ++i) {
    sim::RawImagingOptions imaging;
    imaging.supersampling = 3;
    const cv::Mat image = sim::RenderBoardRaw(camera, board, placements[i], imaging, 100 + i);
    const auto detection = DetectBoard(image, board);
    EXPECT_TRUE(detection.has_value()) << "placement " << i;
    views.push_back({"floor" + std::to_string(i), detection.value_or(BoardDetection{})});
  }
  return views;
}

TEST(CalibrateGround, RecoversTheTiltedCameraAndMakesIdealImagesOfTheRightScale) {
  const camera::RealCameraOptions truth = sim::CalibrationTruthCamera();
  const camera::RealCamera camera(truth);
  const camera::BoardSpec board = camera::ParseBoardSpec("chessboard:9x6:10mm");
  const std::vector<core::Pose2> placements = {
      {-62.0, -42.0, 0.05}, {-18.0, -42.0, -0.05}, {-62.0, -8.0, 0.0}, {-18.0, -8.0, 0.05}};
  GroundOptions options;
  options.mm_per_px = 0.25;
  options.width_px = 560;
  options.height_px = 400;
  const GroundResult result = CalibrateGround(FloorViews(camera, board, placements), board, IntrinsicsOf(truth), options);
  const GroundCalibration& c = result.calibration;
  EXPECT_NEAR(c.height_mm(), truth.height_mm, 0.1);
  EXPECT_NEAR(c.tilt_rad(), std::hypot(truth.tilt_x_rad, truth.tilt_y_rad), 1e-3);
  EXPECT_DOUBLE_EQ(result.coverage, 1.0);
  EXPECT_LT(result.flatness_rms_mm, 0.05);
  for (const GroundViewReport& view : result.views) {
    EXPECT_LT(std::abs(view.scale_error), 5e-4) << view.name;
    EXPECT_LT(view.residual_rms_mm, 0.05) << view.name;
  }

  // The rectification against the truth: every ideal pixel's floor point seen by the real camera.
  const camera::IdealCamera ideal(c.ideal);
  double worst_px = 0.0;
  for (int v = 0; v < ideal.height_px(); v += 20) {
    for (int u = 0; u < ideal.width_px(); u += 20) {
      const auto expected = camera.FloorToPixel(ideal.PixelToCamera(Eigen::Vector2d(u, v)));
      ASSERT_TRUE(expected.has_value());
      worst_px = std::max(worst_px, (c.RawFromIdeal(Eigen::Vector2d(u, v)) - *expected).norm());
    }
  }
  // 0.3 raw px is 0.07 mm on the floor: the tilt from PnP on 80 x 50 mm boards is good to 0.5 mrad.
  EXPECT_LT(worst_px, 0.3) << "height " << c.height_mm() << " tilt " << c.tilt_rad() << " flat "
                            << result.flatness_rms_mm << " scale " << result.views[0].scale_error;

  // A new photograph of the board, rectified, measures the board at the right scale.
  const Rectifier rectifier(c);
  sim::RawImagingOptions imaging;
  imaging.supersampling = 3;
  const cv::Mat raw = sim::RenderBoardRaw(camera, board, core::Pose2(-42.0, -30.0, -0.08), imaging, 9);
  cv::Mat rectified;
  ASSERT_TRUE(rectifier.Rectify(raw, &rectified));
  ASSERT_EQ(rectified.cols, 560);
  const auto detection = DetectBoard(rectified, board);
  ASSERT_TRUE(detection.has_value());
  const IdealBoardMeasurement measured = MeasureIdealBoard(*detection, board, c.ideal);
  EXPECT_LT(std::abs(measured.scale_error), 1e-3);
  EXPECT_LT(measured.residual_rms_mm, 0.03);
  std::printf("height %.3f mm (truth %.1f), tilt %.4f rad, map error <= %.3f px, rectified scale error %.4f %%,"
              " residual %.4f mm\n",
              c.height_mm(), truth.height_mm, c.tilt_rad(), worst_px, 100.0 * measured.scale_error,
              measured.residual_rms_mm);
  EXPECT_FALSE(rectifier.Rectify(cv::Mat(10, 10, CV_8UC1), &rectified));
}

TEST(CalibrateGround, ABoardMissingFromAViewIsBadInputNamingIt) {
  const camera::BoardSpec board = camera::ParseBoardSpec("chessboard:9x6:10mm");
  const std::vector<BoardView> views = {{"empty.png", {}}};
  try {
    CalibrateGround(views, board, IntrinsicsOf(sim::CalibrationTruthCamera()), {});
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_EQ(e.kind(), core::ErrorKind::kInvalidInput);
    EXPECT_NE(std::string(e.what()).find("empty.png"), std::string::npos);
  }
}

GroundCalibration SomeCalibration() {
  GroundCalibration c;
  c.intrinsics = IntrinsicsOf(sim::CalibrationTruthCamera());
  c.ideal = {600, 400, 0.25};
  const camera::RealCameraOptions truth = sim::CalibrationTruthCamera();
  const Eigen::Matrix3d rotation = (Eigen::AngleAxisd(truth.tilt_x_rad, Eigen::Vector3d::UnitX()) *
                                    Eigen::AngleAxisd(truth.tilt_y_rad, Eigen::Vector3d::UnitY()))
                                       .toRotationMatrix();
  c.optical_from_floor = rotation * Eigen::Vector3d(1.0, -1.0, truth.height_mm).asDiagonal();
  return c;
}

TEST(GroundCalibrationFile, RoundTripsAndRejectsEditsAndUnknownKeys) {
  test::ScratchDir dir;
  const GroundCalibration c = SomeCalibration();
  WriteGroundCalibration(dir / "ground.yaml", c, "test");
  const GroundCalibration back = ReadGroundCalibration(dir / "ground.yaml");
  EXPECT_NEAR((back.optical_from_floor - c.optical_from_floor).norm(), 0.0, 1e-12);
  EXPECT_EQ(back.ideal.width_px, 600);
  EXPECT_NEAR(back.intrinsics.kud, c.intrinsics.kud, 1e-15);
  EXPECT_NEAR(back.height_mm(), 200.0, 1e-9);

  std::string text = test::ReadFile(dir / "ground.yaml");
  std::string edited = text;
  const std::size_t at = edited.find("mm_per_px: 0.25");
  ASSERT_NE(at, std::string::npos);
  edited.replace(at, 15, "mm_per_px: 0.3");
  test::WriteFile(dir / "edited.yaml", edited);
  EXPECT_THROW(ReadGroundCalibration(dir / "edited.yaml"), core::Error);
  test::WriteFile(dir / "typo.yaml", text + "tilt_degs: 1\n");
  try {
    ReadGroundCalibration(dir / "typo.yaml");
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("tilt_degs"), std::string::npos) << e.what();
  }
}

TEST(RealCamera, SharesTheGroundCalibrationsFloorFrame) {
  // camera::RealCamera's model written as a ground calibration maps the floor the same way.
  const GroundCalibration c = SomeCalibration();
  const camera::RealCamera camera(sim::CalibrationTruthCamera());
  for (const Eigen::Vector2d& p : {Eigen::Vector2d(10.0, -20.0), Eigen::Vector2d(-60.0, 45.0)}) {
    const auto raw = camera.FloorToPixel(p);
    ASSERT_TRUE(raw.has_value());
    const auto back = c.FloorFromRaw(*raw);
    ASSERT_TRUE(back.has_value());
    EXPECT_NEAR((*back - p).norm(), 0.0, 1e-9);
  }
}

}  // namespace
}  // namespace mosaicloc::calibration
