#include "mosaicloc/dataset/camera_truth.hpp"

#include <fstream>
#include <numbers>
#include <string>

#include <gtest/gtest.h>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::dataset {
namespace {

TEST(CameraTruthCsv, RowsReadBackAsWritten) {
  test::ScratchDir scratch;
  const CameraTruth a{200.25, 0.0012, -0.0034, Eigen::Vector2d(0.5, -0.25)};
  const CameraTruth b{199.5, -0.002, 0.001, Eigen::Vector2d(-1.0, 0.0)};
  std::ofstream(scratch.path() / "camera.csv") << CameraTruthHeader()
                                              << CameraTruthRow(core::Timestamp::FromNanoseconds(100), a)
                                              << CameraTruthRow(core::Timestamp::FromNanoseconds(200), b);
  const std::vector<CameraTruthSample> read = ReadCameraTruth(scratch.path() / "camera.csv");
  ASSERT_EQ(read.size(), 2u);
  EXPECT_EQ(read[1].time.nanoseconds(), 200);
  EXPECT_NEAR(read[0].truth.height_mm, 200.25, 1e-6);
  EXPECT_NEAR(read[0].truth.tilt_x_rad, 0.0012, 1e-9);
  EXPECT_NEAR(read[0].truth.tilt_y_rad, -0.0034, 1e-9);
  EXPECT_NEAR(read[1].truth.centre_offset_mm.x(), -1.0, 1e-6);
}

// A vehicle heading along +y (yaw 90 degrees) whose camera looks 1 mm ahead of and 0.5 mm to
// the left of its mounting point (vehicle axes) looked at floor 1 mm further along +y and 0.5 mm
// towards -x; a pose at a time with no recorded view stays where it was.
TEST(CameraTruthCsv, AViewPoseIsTheMountingPointMovedByTheViewsOffsetInTheVehiclesAxes) {
  const Trajectory truth = {{core::Timestamp::FromNanoseconds(100), core::Pose2(10.0, 20.0, 0.5 * std::numbers::pi)},
                            {core::Timestamp::FromNanoseconds(200), core::Pose2(10.0, 30.0, 0.5 * std::numbers::pi)}};
  const std::vector<CameraTruthSample> views = {
      {core::Timestamp::FromNanoseconds(100), CameraTruth{200.0, 0.005, 0.0, Eigen::Vector2d(1.0, 0.5)}},
      {core::Timestamp::FromNanoseconds(150), CameraTruth{200.0, 0.0, 0.0, Eigen::Vector2d(7.0, 7.0)}}};
  const Trajectory moved = ViewPoses(truth, views);
  ASSERT_EQ(moved.size(), 2u);
  EXPECT_NEAR(moved[0].world_from_vehicle.x_mm(), 9.5, 1e-12);
  EXPECT_NEAR(moved[0].world_from_vehicle.y_mm(), 21.0, 1e-12);
  EXPECT_DOUBLE_EQ(moved[0].world_from_vehicle.yaw_rad(), 0.5 * std::numbers::pi);
  EXPECT_EQ(moved[1].time.nanoseconds(), 200);
  EXPECT_DOUBLE_EQ(moved[1].world_from_vehicle.x_mm(), 10.0);
  EXPECT_DOUBLE_EQ(moved[1].world_from_vehicle.y_mm(), 30.0);
}

TEST(CameraTruthCsv, BadLinesNameTheFileAndLine) {
  test::ScratchDir scratch;
  const auto message = [&](const std::string& body) {
    std::ofstream(scratch.path() / "bad.csv") << CameraTruthHeader() << "100,200,0,0,0,0\n" << body;
    try {
      ReadCameraTruth(scratch.path() / "bad.csv");
    } catch (const core::Error& error) {
      EXPECT_EQ(error.kind(), core::ErrorKind::kInvalidInput);
      return std::string(error.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("200,200,0,0,0\n").find("bad.csv:3: 5 fields, 6 expected"), std::string::npos);
  EXPECT_NE(message("200,-1,0,0,0,0\n").find("bad.csv:3: height_mm -1 is not positive"), std::string::npos);
  EXPECT_NE(message("200,200,0.7,0,0,0\n").find("bad.csv:3: tilt_x_rad 0.7 is not within"), std::string::npos);
  EXPECT_NE(message("200,200,0,0,x,0\n").find("bad.csv:3: centre_dx_mm 'x' is not a number"), std::string::npos);
  EXPECT_NE(message("100,200,0,0,0,0\n").find("bad.csv:3: timestamp_ns does not increase"), std::string::npos);
  EXPECT_THROW(ReadCameraTruth(scratch.path() / "absent.csv"), core::Error);
}

}  // namespace
}  // namespace mosaicloc::dataset
