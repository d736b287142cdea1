#include "mosaicloc/dataset/fixes.hpp"

#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::dataset {
namespace {

using core::Pose2;
using core::Timestamp;

FrameReport Report(double t_s, const Pose2& pose, int status, bool fixed, const std::string& reason = {},
                   const std::string& mode = "track") {
  FrameReport r;
  r.time = Timestamp::FromSeconds(t_s);
  r.world_from_vehicle = pose;
  r.status = status;
  r.quality = fixed ? 0.987 : 0.0;
  r.fixed = fixed;
  r.sigma_mm = fixed ? 0.004 : 2.5;
  r.scale = 1.0 + 0.001 * t_s;
  if (fixed) r.nis = 1.5 + t_s;
  r.reason = reason;
  r.mode = mode;
  return r;
}

TEST(FixesCsv, RowsReadBackAsWritten) {
  test::ScratchDir scratch;
  const std::vector<FrameReport> written = {Report(0.1, Pose2(1.25, -2.5, 0.125), 1, true),
                                            Report(0.2, Pose2(3.0, -4.0, 0.25), 4, false, "off-map", "visual-odometry"),
                                            Report(0.3, Pose2(5.0, 6.0, -0.5), 2, false, "no-match"),
                                            Report(0.4, Pose2(5.0, 6.0, -0.5), 4, false, "off-map", "dead-reckoning"),
                                            Report(0.5, Pose2(5.0, 6.0, -0.5), 5, false, "no-match", "searching")};
  std::string text = FixesCsvHeader();
  for (const FrameReport& r : written) text += FixesCsvRow(r);
  std::ofstream(scratch.path() / "fixes.csv") << text;
  const std::vector<FrameReport> read = ReadFixesCsv(scratch.path() / "fixes.csv");
  ASSERT_EQ(read.size(), written.size());
  for (std::size_t i = 0; i < read.size(); ++i) {
    EXPECT_EQ(read[i].time, written[i].time);
    EXPECT_NEAR(Distance(read[i].world_from_vehicle, written[i].world_from_vehicle), 0.0, 1e-4);
    EXPECT_EQ(read[i].status, written[i].status);
    EXPECT_NEAR(read[i].quality, written[i].quality, 1e-3);
    EXPECT_EQ(read[i].fixed, written[i].fixed);
    EXPECT_NEAR(read[i].sigma_mm, written[i].sigma_mm, 1e-4);
    EXPECT_NEAR(read[i].scale, written[i].scale, 1e-6);
    ASSERT_EQ(read[i].nis.has_value(), written[i].nis.has_value());
    if (read[i].nis) {
      EXPECT_NEAR(*read[i].nis, *written[i].nis, 1e-3);
    }
    EXPECT_EQ(read[i].reason, written[i].reason);
    EXPECT_EQ(read[i].mode, written[i].mode);
  }
  EXPECT_THROW(FixesCsvRow(Report(0.4, Pose2(), 3, false, "a, b")), core::Error);
  EXPECT_THROW(FixesCsvRow(Report(0.4, Pose2(), 3, false, "off-map", "mapping")), core::Error);
}

TEST(FixesCsv, BadLinesNameTheFileAndLine) {
  test::ScratchDir scratch;
  const auto message = [&](const std::string& body) {
    std::ofstream(scratch.path() / "bad.csv") << FixesCsvHeader() << "100,1,2,0.1,1,990,1,0.004,\n" << body;
    try {
      ReadFixesCsv(scratch.path() / "bad.csv");
    } catch (const core::Error& error) {
      EXPECT_EQ(error.kind(), core::ErrorKind::kInvalidInput);
      return std::string(error.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("200,1,2,0.1,6,990,1,0.004,\n").find("bad.csv:3: status 6 is outside [0, 5]"), std::string::npos);
  EXPECT_NE(message("200,1,2,0.1,1,990,1,0.004\n").find("bad.csv:3: 8 fields, 12 expected"), std::string::npos);
  EXPECT_NE(message("200,1,2,0.1,1,990,1,0.004,1,-2,\n").find("bad.csv:3: nis is negative"), std::string::npos);
  EXPECT_NE(message("200,1,2,0.1,1,990,1,0.004,1,,,flying\n").find("bad.csv:3: mode 'flying' is not one of"),
            std::string::npos);
  EXPECT_NE(message("200,1,2,0.1,1,990,1,0.004,2.5,\n").find("bad.csv:3: scale 2.5 is outside (0, 2)"),
            std::string::npos);
  EXPECT_NE(message("200,1,2,0.1,1,990,1,0.004,high,\n").find("bad.csv:3: scale 'high' is not a number"),
            std::string::npos);
  EXPECT_NE(message("200,1,x,0.1,1,990,1,0.004,\n").find("bad.csv:3: y_mm 'x' is not a number"), std::string::npos);
  EXPECT_NE(message("100,1,2,0.1,1,990,1,0.004,\n").find("bad.csv:3: timestamp_ns does not increase"),
            std::string::npos);
  EXPECT_NE(message("200,1,2,0.1,1,990,2,0.004,\n").find("bad.csv:3: fix 2 is outside [0, 1]"), std::string::npos);
}

// A file from before the scale column (nine fields) reads with scale 1.
TEST(FixesCsv, RowsWithoutTheScaleReadWithScaleOne) {
  test::ScratchDir scratch;
  std::ofstream(scratch.path() / "old.csv") << "#timestamp_ns,x_mm,y_mm,yaw_rad,status,quality,fix,sigma_mm,reason\n"
                                            << "100,1,2,0.1,4,0,0,2.5,off-map\n";
  const std::vector<FrameReport> read = ReadFixesCsv(scratch.path() / "old.csv");
  ASSERT_EQ(read.size(), 1U);
  EXPECT_EQ(read[0].scale, 1.0);
  EXPECT_EQ(read[0].reason, "off-map");
}

// Fixes are checked against the truth at their own time; a fix a floor period off is wrong
// whatever its status and quality; dead reckoning off the map is measured, not counted.
TEST(CheckFixes, CountsFixesOffTheTruthAndMeasuresDeadReckoningOffTheMap) {
  Trajectory truth;
  for (int i = 0; i <= 10; ++i) truth.push_back({Timestamp::FromSeconds(0.1 * i), Pose2(10.0 * i, 0.0, 0.0)});
  const std::vector<FrameReport> reports = {
      Report(0.1, Pose2(10.0005, 0.0, 0.0), 1, true),           // on the truth (interpolated at 0.1 s: 10 mm)
      Report(0.15, Pose2(15.0, 0.5, 0.0), 2, true),             // half a millimetre off: not wrong
      Report(0.2, Pose2(20.0, 3.0, 0.0), 4, false, "off-map"),  // dead reckoning, 3 mm off
      Report(0.3, Pose2(30.0 + 512.0, 0.0, 0.0), 2, true),      // one period away, quality high
      Report(0.4, Pose2(40.0, 1.5, 0.0), 1, true),              // 1.5 mm off
      Report(2.0, Pose2(0.0, 0.0, 0.0), 1, true),               // no truth then: not checked
  };
  const FixCheck check = CheckFixes(reports, truth);
  EXPECT_EQ(check.checked_fixes, 4);
  EXPECT_EQ(check.wrong_fixes, 2);
  ASSERT_TRUE(check.max_wrong_fix_mm.has_value());
  EXPECT_NEAR(*check.max_wrong_fix_mm, 512.0, 1e-6);
  EXPECT_EQ(check.off_map_frames, 1);
  ASSERT_TRUE(check.off_map_max_error_mm.has_value());
  EXPECT_NEAR(*check.off_map_max_error_mm, 3.0, 1e-6);
  const FixCheck clean = CheckFixes({reports[0], reports[1]}, truth);
  EXPECT_EQ(clean.wrong_fixes, 0);
  EXPECT_FALSE(clean.max_wrong_fix_mm.has_value());
  EXPECT_NEAR(*clean.max_fix_error_mm, 0.5, 1e-6);
  EXPECT_NEAR(*clean.fix_error_rms_mm, std::sqrt(0.5 * (0.0005 * 0.0005 + 0.5 * 0.5)), 1e-6);
}

TEST(CheckReentries, CountsFramesFromTheReturnToTheFirstFix) {
  Trajectory truth;
  for (int i = 0; i <= 20; ++i) truth.push_back({Timestamp::FromSeconds(0.1 * i), Pose2(10.0 * i, 0.0, 0.0)});
  std::vector<FrameReport> reports;
  std::vector<double> mapped;
  // on, off, off, back (miss, miss, a fix 0.01 mm off), at the edge (not off), on, off, partly
  // back (a fix 0.02 mm off before the view is wholly on the map), back, on
  const std::vector<double> shares = {1.0, 0.2, 0.0, 1.0, 1.0, 1.0, 0.9, 1.0, 0.3, 0.7, 1.0, 1.0};
  const std::string fixed = "100001010100";
  for (std::size_t i = 0; i < shares.size(); ++i) {
    const double t = 0.1 * static_cast<double>(i + 1);
    const double error = i == 5 ? 0.01 : i == 9 ? 0.02 : 0.0;
    reports.push_back(Report(t, Pose2(100.0 * t + error, 0.0, 0.0), fixed[i] == '1' ? 1 : 4, fixed[i] == '1'));
    mapped.push_back(shares[i]);
  }
  const ReentryCheck check = CheckReentries(reports, mapped, truth);
  EXPECT_EQ(check.reentries, 2) << "grazing the edge is no return";
  ASSERT_TRUE(check.frames_to_fix_max.has_value());
  EXPECT_EQ(*check.frames_to_fix_max, 3);
  ASSERT_TRUE(check.first_fix_error_max_mm.has_value());
  EXPECT_NEAR(*check.first_fix_error_max_mm, 0.02, 1e-6) << "the first fix back, while partly off the map";
  // A return that never gets a fix counts its frames on the map.
  const ReentryCheck unfixed =
      CheckReentries({reports[0], reports[1], reports[3], reports[4]}, {1.0, 0.0, 1.0, 1.0}, truth);
  EXPECT_EQ(unfixed.reentries, 1);
  EXPECT_EQ(*unfixed.frames_to_fix_max, 2);
  EXPECT_FALSE(unfixed.first_fix_error_max_mm.has_value());
  EXPECT_THROW(CheckReentries(reports, {1.0}, truth), core::Error);
}

}  // namespace
}  // namespace mosaicloc::dataset
