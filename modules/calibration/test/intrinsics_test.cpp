#include "mosaicloc/calibration/intrinsics.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "mosaicloc/camera/board.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/sim/raw_imaging.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::calibration {
namespace {

// The synthetic camera: known intrinsics and distortion, photographs through the real-camera model.
// Three samples per pixel along each axis keep the rendering (and the tests under the
// sanitizers) fast; the edges stay smooth enough for sub-pixel detection.
sim::RawImagingOptions Imaging() {
  sim::RawImagingOptions options;
  options.supersampling = 3;
  return options;
}

std::vector<BoardView> Detect(const std::vector<sim::BoardShot>& shots, const camera::BoardSpec& board) {
  std::vector<BoardView> views;
  for (std::size_t i = 0; i < shots.size(); ++i) {
    BoardView view;
    view.name = "shot" + std::to_string(i);
    const auto detection = DetectBoard(shots[i].image, board);
    if (detection) view.detection = *detection;
    views.push_back(view);
  }
  return views;
}

void ExpectRecovered(const Intrinsics& estimate, const camera::RealCameraOptions& truth, const char* who) {
  SCOPED_TRACE(who);
  EXPECT_LT(std::abs(estimate.fx_px / truth.fx_px - 1.0), 0.002) << estimate.fx_px;
  EXPECT_LT(std::abs(estimate.fy_px / truth.fy_px - 1.0), 0.002) << estimate.fy_px;
  EXPECT_LT(std::abs(estimate.cx_px / truth.cx_px - 1.0), 0.002) << estimate.cx_px;
  EXPECT_LT(std::abs(estimate.cy_px / truth.cy_px - 1.0), 0.002) << estimate.cy_px;
  EXPECT_LT(std::abs(estimate.kud / truth.k1 - 1.0), 0.02) << estimate.kud;
}

TEST(CalibrateIntrinsics, RecoversASyntheticCameraFromChessboardShots) {
  const camera::BoardSpec board = camera::ParseBoardSpec("chessboard:9x6:20mm");
  const camera::RealCameraOptions truth = sim::CalibrationTruthCamera();
  const auto shots = sim::RenderIntrinsicsShots(truth, board, 12, 0.42, Imaging(), 11);
  std::vector<BoardView> views = Detect(shots, board);
  // A photograph with no board in it is reported, not used.
  views.push_back({"blank.png", {}});
  const IntrinsicsResult result = CalibrateIntrinsics(views, board, truth.width_px, truth.height_px, {});
  ExpectRecovered(result.visp.intrinsics, truth, "ViSP");
  ExpectRecovered(result.opencv.intrinsics, truth, "OpenCV");
  EXPECT_LT(result.visp.rms_px, 0.15);
  EXPECT_LT(result.opencv.rms_px, 0.15);
  // The two libraries minimise the same error over the same detections.
  EXPECT_NEAR(result.visp.rms_px, result.opencv.rms_px, 0.01);
  ASSERT_EQ(result.views.size(), views.size());
  EXPECT_FALSE(result.views.back().used);
  EXPECT_EQ(result.views.back().rejected_because, "board not found");
  std::printf("truth   fx %.2f fy %.2f cx %.2f cy %.2f k1 %.5f\n", truth.fx_px, truth.fy_px, truth.cx_px,
              truth.cy_px, truth.k1);
  for (const auto& [who, e] : {std::pair{"ViSP", result.visp}, std::pair{"OpenCV", result.opencv}}) {
    std::printf("%-7s fx %.2f fy %.2f cx %.2f cy %.2f k1 %.5f rms %.4f px\n", who, e.intrinsics.fx_px,
                e.intrinsics.fy_px, e.intrinsics.cx_px, e.intrinsics.cy_px, e.intrinsics.kud, e.rms_px);
  }
}

TEST(CalibrateIntrinsics, RecoversASyntheticCameraFromCircleGridShots) {
  const camera::BoardSpec board = camera::ParseBoardSpec("circles:7x5:24mm");
  const camera::RealCameraOptions truth = sim::CalibrationTruthCamera();
  const auto shots = sim::RenderIntrinsicsShots(truth, board, 8, 0.3, Imaging(), 5);
  const IntrinsicsResult result = CalibrateIntrinsics(Detect(shots, board), board, truth.width_px, truth.height_px, {});
  EXPECT_GE(result.used.size(), 7u);
  // Blob centroids are not the projected circle centres under perspective: looser bounds.
  EXPECT_LT(std::abs(result.visp.intrinsics.fx_px / truth.fx_px - 1.0), 0.01);
  EXPECT_LT(std::abs(result.visp.intrinsics.kud / truth.k1 - 1.0), 0.1);
  EXPECT_NEAR(result.visp.intrinsics.fx_px, result.opencv.intrinsics.fx_px, 0.002 * truth.fx_px);
}

TEST(CalibrateIntrinsics, RejectsAnOutlierViewNamingIt) {
  const camera::BoardSpec board = camera::ParseBoardSpec("chessboard:9x6:20mm");
  const camera::RealCameraOptions truth = sim::CalibrationTruthCamera();
  const auto shots = sim::RenderIntrinsicsShots(truth, board, 6, 0.4, Imaging(), 3);
  std::vector<BoardView> views = Detect(shots, board);
  for (auto& p : views[2].detection.points_px) p += Eigen::Vector2d(std::sin(7.0 * p.y()), std::cos(5.0 * p.x()));
  const IntrinsicsResult result = CalibrateIntrinsics(views, board, truth.width_px, truth.height_px, {});
  EXPECT_FALSE(result.views[2].used);
  EXPECT_NE(result.views[2].rejected_because.find("outlier"), std::string::npos) << result.views[2].rejected_because;
  EXPECT_EQ(result.used.size(), 5u);
  EXPECT_LT(std::abs(result.visp.intrinsics.fx_px / truth.fx_px - 1.0), 0.005);
}

TEST(CalibrateIntrinsics, TooFewViewsIsBadInputNamingTheRejected) {
  const camera::BoardSpec board = camera::ParseBoardSpec("chessboard:9x6:20mm");
  std::vector<BoardView> views = {{"a.png", {}}, {"b.png", {}}};
  try {
    CalibrateIntrinsics(views, board, 640, 480, {});
    FAIL() << "no error";
  } catch (const core::Error& e) {
    EXPECT_EQ(e.kind(), core::ErrorKind::kInvalidInput);
    EXPECT_NE(std::string(e.what()).find("a.png (board not found)"), std::string::npos) << e.what();
  }
}

TEST(VispCameraXml, RoundTripsAndOverwrites) {
  test::ScratchDir dir;
  Intrinsics k{640, 480, 801.5, 799.25, 321.125, 238.5, -0.125, 0.13};
  const auto file = dir / "camera.xml";
  WriteVispCameraXml(file, k, "floor", "test");
  k.fx_px = 900.0;
  WriteVispCameraXml(file, k, "floor", "test");  // replaces, does not append
  const Intrinsics back = ReadVispCameraXml(file, "floor");
  EXPECT_NEAR(back.fx_px, 900.0, 1e-6);
  EXPECT_NEAR(back.fy_px, k.fy_px, 1e-6);
  EXPECT_NEAR(back.cx_px, k.cx_px, 1e-6);
  EXPECT_NEAR(back.cy_px, k.cy_px, 1e-6);
  EXPECT_NEAR(back.kud, k.kud, 1e-9);
  EXPECT_NEAR(back.kdu, k.kdu, 1e-9);
  EXPECT_EQ(back.width_px, 640);
  EXPECT_NEAR(ReadVispCameraXml(file, "").fx_px, 900.0, 1e-6);  // the first camera
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()), std::filesystem::directory_iterator()), 1);
  EXPECT_THROW(ReadVispCameraXml(dir / "missing.xml", ""), core::Error);
  EXPECT_THROW(ReadVispCameraXml(file, "another"), core::Error);
  EXPECT_THROW(WriteVispCameraXml(dir / "no" / "such" / "dir.xml", k, "floor", ""), core::Error);
}

TEST(Distortion, UndistortInvertsProject) {
  const Intrinsics k{640, 480, 800, 790, 320, 240, -0.2, 0.0};
  for (const Eigen::Vector3d& p : {Eigen::Vector3d(0.3, -0.2, 1.0), Eigen::Vector3d(-0.35, 0.25, 1.0)}) {
    const Eigen::Vector2d pixel = ProjectWithDistortion(k, p);
    EXPECT_NEAR((UndistortToNormalized(k, pixel) - p.head<2>()).norm(), 0.0, 1e-12);
  }
}

// ViSP's own calibration photographs (package visp-images-data): a 6x6 circle grid.
TEST(CalibrateIntrinsics, VispGrid36ImagesCalibrateAndAgreeWithOpenCv) {
  const std::filesystem::path folder = "/usr/share/visp-images-data/ViSP-images/calibration";
  if (!std::filesystem::exists(folder / "grid36-01.pgm")) {
    GTEST_SKIP() << "ViSP's calibration images are absent (" << folder << "): install visp-images-data";
  }
  const camera::BoardSpec board = camera::ParseBoardSpec("circles:6x6:34mm");
  std::vector<BoardView> views;
  int width = 0, height = 0;
  for (int i = 1; i <= 4; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "grid36-%02d.pgm", i);
    const cv::Mat image = cv::imread((folder / name).string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(image.empty()) << name;
    width = image.cols;
    height = image.rows;
    const auto detection = DetectBoard(image, board);
    ASSERT_TRUE(detection.has_value()) << name;
    views.push_back({name, *detection});
  }
  const IntrinsicsResult result = CalibrateIntrinsics(views, board, width, height, {});
  EXPECT_EQ(result.used.size(), 4u);
  EXPECT_LT(result.visp.rms_px, 0.5);
  EXPECT_LT(result.opencv.rms_px, 0.5);
  EXPECT_NEAR(result.visp.intrinsics.fx_px / result.opencv.intrinsics.fx_px, 1.0, 0.01);
  EXPECT_NEAR(result.visp.intrinsics.cx_px, result.opencv.intrinsics.cx_px, 5.0);
  EXPECT_NEAR(result.visp.intrinsics.cy_px, result.opencv.intrinsics.cy_px, 5.0);
  for (const auto& [who, e] : {std::pair{"ViSP", result.visp}, std::pair{"OpenCV", result.opencv}}) {
    std::printf("%-7s fx %.2f fy %.2f cx %.2f cy %.2f kud %.5f kdu %.5f rms %.4f px\n", who, e.intrinsics.fx_px,
                e.intrinsics.fy_px, e.intrinsics.cx_px, e.intrinsics.cy_px, e.intrinsics.kud, e.intrinsics.kdu,
                e.rms_px);
  }
}

}  // namespace
}  // namespace mosaicloc::calibration
