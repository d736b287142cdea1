#include "mosaicloc/dataset/trajectory.hpp"

#include <chrono>
#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::dataset {
namespace {

using std::chrono::milliseconds;

// The message of the core::Error (invalid input) that `read` throws, or "" if it throws none.
template <typename F>
std::string InvalidInputMessage(F&& read) {
  try {
    read();
  } catch (const core::Error& error) {
    EXPECT_EQ(error.kind(), core::ErrorKind::kInvalidInput) << error.what();
    return error.what();
  }
  ADD_FAILURE() << "no core::Error thrown";
  return "";
}

TEST(TumTime, ParsesDigitsExactly) {
  EXPECT_EQ(ParseSeconds("1700000000.123456789")->nanoseconds(), 1'700'000'000'123'456'789);
  EXPECT_EQ(ParseSeconds("1700000000.999999999")->nanoseconds(), 1'700'000'000'999'999'999);
  EXPECT_EQ(ParseSeconds("12")->nanoseconds(), 12'000'000'000);
  EXPECT_EQ(ParseSeconds("-0.5")->nanoseconds(), -500'000'000);
  EXPECT_EQ(ParseSeconds("+.25")->nanoseconds(), 250'000'000);
  EXPECT_EQ(ParseSeconds("1.7e9")->nanoseconds(), 1'700'000'000'000'000'000);
  EXPECT_EQ(ParseSeconds("17E-1")->nanoseconds(), 1'700'000'000);
  EXPECT_EQ(ParseSeconds("0000.000")->nanoseconds(), 0);
  // Beyond 9 decimals: rounded to the nearest nanosecond, halves away from zero.
  EXPECT_EQ(ParseSeconds("1.0000000004")->nanoseconds(), 1'000'000'000);
  EXPECT_EQ(ParseSeconds("1.0000000005")->nanoseconds(), 1'000'000'001);
  EXPECT_EQ(ParseSeconds("-1.0000000005")->nanoseconds(), -1'000'000'001);
  EXPECT_EQ(ParseSeconds("0.00000000049")->nanoseconds(), 0);
  EXPECT_EQ(ParseSeconds("9223372036.854775807")->nanoseconds(), 9'223'372'036'854'775'807);
  for (const char* bad : {"", "-", ".", "abc", "1.2.3", "1e", "1e+", "1 ", "0x10", "nan", "inf",
                          "9223372036.854775808", "1e20"}) {
    EXPECT_FALSE(ParseSeconds(bad).has_value()) << "'" << bad << "'";
  }
}

TEST(TumTime, FormatsNineDecimalsAndRoundTrips) {
  EXPECT_EQ(FormatSeconds(core::Timestamp::FromNanoseconds(1'700'000'000'123'456'789)),
            "1700000000.123456789");
  EXPECT_EQ(FormatSeconds(core::Timestamp::FromNanoseconds(-500'000'000)), "-0.500000000");
  EXPECT_EQ(FormatSeconds(core::Timestamp::FromNanoseconds(7)), "0.000000007");
  std::mt19937_64 random(7);
  std::uniform_int_distribution<std::int64_t> ns(-4'000'000'000'000'000'000,
                                                 4'000'000'000'000'000'000);
  for (int i = 0; i < 1000; ++i) {
    const auto time = core::Timestamp::FromNanoseconds(ns(random));
    EXPECT_EQ(ParseSeconds(FormatSeconds(time)), time);
  }
}

TEST(Tum, RoundTripIsExactToTheNanosecondAndMicrometre) {
  test::ScratchDir dir;
  std::mt19937 random(42);
  std::uniform_real_distribution<double> position_mm(-50'000.0, 50'000.0);
  std::uniform_real_distribution<double> yaw_rad(-std::numbers::pi, std::numbers::pi);
  std::uniform_int_distribution<std::int64_t> step_ns(1, 50'000'000);
  Trajectory written;
  std::int64_t ns = 1'700'000'000'123'456'789;
  for (int i = 0; i < 2000; ++i) {
    ns += step_ns(random);
    written.push_back({core::Timestamp::FromNanoseconds(ns),
                       core::Pose2(position_mm(random), position_mm(random), yaw_rad(random))});
  }
  written.push_back({core::Timestamp::FromNanoseconds(ns + 1), core::Pose2(0.0, -0.0, std::numbers::pi)});
  const auto file = dir / "trajectory.tum";
  WriteTum(file, written);
  const Trajectory read = ReadTum(file);
  ASSERT_EQ(read.size(), written.size());
  for (std::size_t i = 0; i < read.size(); ++i) {
    EXPECT_EQ(read[i].time, written[i].time) << i;
    EXPECT_LT(core::Distance(read[i].world_from_vehicle, written[i].world_from_vehicle), 1e-6) << i;
    EXPECT_NEAR(core::YawDifference(read[i].world_from_vehicle, written[i].world_from_vehicle), 0.0,
                1e-11)
        << i;
  }
  // Only the file itself: the temporary was renamed.
  int entries = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir.path())) {
    EXPECT_EQ(entry.path().filename(), "trajectory.tum");
    ++entries;
  }
  EXPECT_EQ(entries, 1);
}

TEST(Tum, ReadsCommentsBlankLinesTabsCrlfAndShortQuaternions) {
  test::ScratchDir dir;
  const auto file = dir / "tum.txt";
  test::WriteFile(file,
                  "# timestamp tx ty tz qx qy qz qw\r\n"
                  "\n"
                  "   \t\n"
                  "1305031098.6659\t1.3563 0.6305 0.0 0.0 0.0 0.7071 0.7071\r\n"
                  "  # indented comment\n"
                  "1305031098.7 -2 3e-3 0.5 0 0 -1 0");
  const Trajectory trajectory = ReadTum(file);
  ASSERT_EQ(trajectory.size(), 2u);
  EXPECT_EQ(trajectory[0].time.nanoseconds(), 1'305'031'098'665'900'000);
  EXPECT_NEAR(trajectory[0].world_from_vehicle.x_mm(), 1356.3, 1e-9);
  EXPECT_NEAR(trajectory[0].world_from_vehicle.y_mm(), 630.5, 1e-9);
  EXPECT_NEAR(trajectory[0].world_from_vehicle.yaw_rad(), std::numbers::pi / 2, 1e-9);
  EXPECT_EQ(trajectory[1].time.nanoseconds(), 1'305'031'098'700'000'000);
  EXPECT_NEAR(trajectory[1].world_from_vehicle.x_mm(), -2000.0, 1e-9);
  EXPECT_NEAR(trajectory[1].world_from_vehicle.y_mm(), 3.0, 1e-9);
  // q = (0, 0, -1, 0) is a rotation by -pi = pi about z.
  EXPECT_NEAR(std::abs(trajectory[1].world_from_vehicle.yaw_rad()), std::numbers::pi, 1e-12);
}

struct BadLine {
  const char* line;
  const char* reason;  // a part of the expected message
};

TEST(Tum, RejectsEachKindOfBadLineWithFileAndLine) {
  test::ScratchDir dir;
  const auto file = dir / "bad.tum";
  const std::vector<BadLine> cases = {
      {"2.0 1 2 0 0 0 0", "expected 8 fields"},
      {"2.0 1 2 0 0 0 0 1 9", "expected 8 fields"},
      {"2.0 1 abc 0 0 0 0 1", "field 3 (y_m) 'abc' is not a number"},
      {"2.0 1 2 0 0 0 0 1x", "field 8 (qw) '1x' is not a number"},
      {"2,0 1 2 0 0 0 0 1", "field 1 (timestamp_s)"},
      {"2.0 nan 2 0 0 0 0 1", "field 2 (x_m) 'nan' is not finite"},
      {"2.0 1 2 inf 0 0 0 1", "field 4 (z_m) 'inf' is not finite"},
      {"1.0 1 2 0 0 0 0 1", "not after the previous pose's 1.000000000 s (line 2)"},
      {"0.5 1 2 0 0 0 0 1", "timestamps must strictly increase"},
      {"2.0 1 2 0 0 0 0 1.1", "has norm 1.1, not 1"},
      {"2.0 1 2 0 0 0 0 0", "has norm 0, not 1"},
      {"2.0 1 2 0 0.3826834 0 0 0.9238795", "rotation is not about z"},
      {"2.0 1 2 0 0 0.02 0 0.9998", "rotation is not about z"},
  };
  for (const BadLine& bad : cases) {
    test::WriteFile(
        file, std::string("# header\n1.0 0 0 0 0 0 0 1\n") + bad.line + "\n3.0 0 0 0 0 0 0 1\n");
    const std::string message = InvalidInputMessage([&] { ReadTum(file); });
    EXPECT_EQ(message.rfind(file.string() + ":3: ", 0), 0u) << bad.line << " -> " << message;
    EXPECT_NE(message.find(bad.reason), std::string::npos) << bad.line << " -> " << message;
  }
}

TEST(Tum, AcceptsSmallTiltAndNormErrors) {
  test::ScratchDir dir;
  const auto file = dir / "ok.tum";
  // Tilt 2 asin(0.004) = 0.008 rad and norm 1.0004 are within the tolerances.
  test::WriteFile(file, "1.0 0 0 0 0.004 0 0 1.0004\n");
  const Trajectory trajectory = ReadTum(file);
  ASSERT_EQ(trajectory.size(), 1u);
  EXPECT_NEAR(trajectory[0].world_from_vehicle.yaw_rad(), 0.0, 1e-12);
}

TEST(Tum, EmptyOrMissingFileNamesTheFile) {
  test::ScratchDir dir;
  const auto empty = dir / "empty.tum";
  test::WriteFile(empty, "");
  EXPECT_NE(InvalidInputMessage([&] { ReadTum(empty); }).find(empty.string() + ": no pose"),
            std::string::npos);
  test::WriteFile(empty, "# only a comment\n\n");
  EXPECT_NE(InvalidInputMessage([&] { ReadTum(empty); }).find(empty.string() + ": no pose"),
            std::string::npos);
  const auto missing = dir / "missing.tum";
  EXPECT_NE(InvalidInputMessage([&] { ReadTum(missing); }).find(missing.string() + ": cannot open"),
            std::string::npos);
}

TEST(Tum, UnsortedTrajectoryIsNotWrittenAndTheOldFileStays) {
  test::ScratchDir dir;
  const auto file = dir / "keep.tum";
  test::WriteFile(file, "old");
  const Trajectory unsorted = {{core::Timestamp::FromNanoseconds(2), core::Pose2()},
                               {core::Timestamp::FromNanoseconds(2), core::Pose2()}};
  InvalidInputMessage([&] { WriteTum(file, unsorted); });
  EXPECT_EQ(test::ReadFile(file), "old");
}

// A vehicle driving a circle arc: constant body twist (speed 400 mm/s, yaw rate 0.5 rad/s).
core::Pose2 ArcPose(double t_s) {
  const core::Pose2 start(1200.0, -300.0, 0.3);
  return start * core::Pose2::Exp(Eigen::Vector3d(400.0, 0.0, 0.5) * t_s);
}

TEST(PoseAt, InterpolatesAConstantCurvatureArcExactly) {
  Trajectory arc;
  for (int i = 0; i <= 50; ++i) {
    arc.push_back({core::Timestamp::FromNanoseconds(i * 100'000'000LL), ArcPose(i * 0.1)});
  }
  std::mt19937 random(3);
  std::uniform_int_distribution<std::int64_t> ns(0, 5'000'000'000);
  for (int i = 0; i < 500; ++i) {
    const auto t = core::Timestamp::FromNanoseconds(ns(random));
    const std::optional<core::Pose2> pose = PoseAt(arc, t, milliseconds(100));
    ASSERT_TRUE(pose.has_value());
    const core::Pose2 truth = ArcPose(t.seconds());
    EXPECT_LT(core::Distance(*pose, truth), 1e-9);
    EXPECT_NEAR(core::YawDifference(*pose, truth), 0.0, 1e-12);
  }
  // A sample's own time gives the sample.
  const auto at_sample = PoseAt(arc, arc[7].time, milliseconds(1));
  ASSERT_TRUE(at_sample.has_value());
  EXPECT_EQ(at_sample->x_mm(), arc[7].world_from_vehicle.x_mm());
  EXPECT_EQ(at_sample->yaw_rad(), arc[7].world_from_vehicle.yaw_rad());
}

TEST(PoseAt, NothingOutsideOrInGaps) {
  const Trajectory trajectory = {
      {core::Timestamp::FromNanoseconds(0), core::Pose2(0, 0, 0)},
      {core::Timestamp::FromNanoseconds(100'000'000), core::Pose2(10, 0, 0)},
      {core::Timestamp::FromNanoseconds(400'000'000), core::Pose2(40, 0, 0)},
  };
  EXPECT_FALSE(PoseAt(trajectory, core::Timestamp::FromNanoseconds(-1), milliseconds(100)));
  EXPECT_FALSE(
      PoseAt(trajectory, core::Timestamp::FromNanoseconds(400'000'001), milliseconds(500)));
  EXPECT_FALSE(PoseAt({}, core::Timestamp::FromNanoseconds(0), milliseconds(100)));
  // 300 ms gap between the last two samples.
  EXPECT_FALSE(
      PoseAt(trajectory, core::Timestamp::FromNanoseconds(250'000'000), milliseconds(299)));
  const auto bridged =
      PoseAt(trajectory, core::Timestamp::FromNanoseconds(250'000'000), milliseconds(300));
  ASSERT_TRUE(bridged.has_value());
  EXPECT_NEAR(bridged->x_mm(), 25.0, 1e-12);
  const auto first =
      PoseAt(trajectory, core::Timestamp::FromNanoseconds(50'000'000), milliseconds(100));
  ASSERT_TRUE(first.has_value());
  EXPECT_NEAR(first->x_mm(), 5.0, 1e-12);
  // A sample inside a gap is still exact.
  EXPECT_TRUE(PoseAt(trajectory, core::Timestamp::FromNanoseconds(400'000'000), milliseconds(1)));
}

}  // namespace
}  // namespace mosaicloc::dataset
