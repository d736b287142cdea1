#include "mosaicloc/core/wheel_geometry.hpp"

#include <cmath>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace mosaicloc::core {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

std::vector<std::string> Read(const std::string& text, WheelGeometry* wheels, bool required) {
  const YAML::Node node = YAML::Load(text);
  YamlProblems problems;
  YamlMap root = YamlMap::Root(node, "run.yaml", &problems);
  YamlMap vehicle = root.OptionalMap("vehicle");
  ReadWheelGeometry(vehicle, wheels, required);
  vehicle.Finish();
  root.Finish();
  return problems.messages();
}

TEST(WheelGeometry, ChecksEachValueNamingIt) {
  std::string why;
  EXPECT_TRUE(WheelGeometry{}.Check(&why));
  WheelGeometry bad;
  bad.right_wheel_radius_mm = 0.0;
  EXPECT_FALSE(bad.Check(&why));
  EXPECT_THAT(why, HasSubstr("right_wheel_radius_mm must be > 0"));
  bad = {};
  bad.track_width_mm = std::nan("");
  EXPECT_FALSE(bad.Check(&why));
  EXPECT_THAT(why, HasSubstr("track_width_mm"));
  bad = {};
  bad.ticks_per_revolution = 0;
  EXPECT_FALSE(bad.Check(&why));
  EXPECT_THAT(why, HasSubstr("ticks_per_revolution"));
}

TEST(WheelGeometry, OptionalKeysKeepTheDefaultsAndCheckReportsAtTheKeysLine) {
  WheelGeometry wheels;
  EXPECT_TRUE(Read("vehicle:\n  track_width_mm: 480\n", &wheels, false).empty());
  EXPECT_EQ(wheels.track_width_mm, 480.0);
  EXPECT_EQ(wheels.left_wheel_radius_mm, 75.0);
  wheels = {};
  EXPECT_THAT(Read("vehicle:\n  track_width_mm: 480\n  left_wheel_radius_mm: -2\n", &wheels, false),
              ElementsAre("run.yaml:3: vehicle.left_wheel_radius_mm: must be > 0 mm (got -2.000000)"));
  wheels = {};
  // An absent optional mapping is not checked: the defaults stand.
  EXPECT_TRUE(Read("other: 1\n", &wheels, false).size() == 1);  // only `other` is unknown
}

TEST(WheelGeometry, RequiredKeysAreAllNamedWhenMissing) {
  WheelGeometry wheels;
  const auto problems = Read("vehicle:\n  track_width_mm: 480\n", &wheels, true);
  ASSERT_EQ(problems.size(), 3u);
  EXPECT_THAT(problems[0], HasSubstr("vehicle.left_wheel_radius_mm: missing required key"));
  EXPECT_THAT(problems[2], HasSubstr("vehicle.ticks_per_revolution: missing required key"));
}

TEST(WheelGeometry, ATricycleHasItsOwnKeysAndTheOthersAreProblems) {
  WheelGeometry wheels;
  EXPECT_TRUE(Read("vehicle:\n  kind: tricycle\n  wheelbase_mm: 1400\n  steering_offset_deg: -0.4\n", &wheels, false)
                  .empty());
  EXPECT_EQ(wheels.kind, DriveKind::kTricycle);
  EXPECT_EQ(wheels.wheelbase_mm, 1400.0);
  EXPECT_NEAR(wheels.SteeringRad(0), -0.4 * M_PI / 180.0, 1e-15);
  EXPECT_NEAR(wheels.SteeringRad(16384), M_PI / 2 - 0.4 * M_PI / 180.0, 1e-15);  // a quarter of 65536
  wheels = {};
  EXPECT_THAT(Read("vehicle:\n  kind: tricycle\n  track_width_mm: 480\n", &wheels, false),
              ElementsAre(HasSubstr("track_width_mm")));
  wheels = {};
  EXPECT_THAT(Read("vehicle:\n  kind: tricycle\n  steering_offset_deg: 60\n", &wheels, false),
              ElementsAre(HasSubstr("steering_offset_deg: must be within +-45")));
  wheels = {};
  EXPECT_THAT(Read("vehicle:\n  kind: forklift\n", &wheels, false), ElementsAre(HasSubstr("kind")));
  wheels = {};  // a dataset names every key of its kind
  EXPECT_THAT(Read("vehicle:\n  kind: tricycle\n  wheelbase_mm: 1400\n", &wheels, true),
              testing::Contains(HasSubstr("drive_wheel_radius_mm")));
}

TEST(WheelGeometry, AMecanumVehicleHasItsOwnKeysAndTheOthersAreProblems) {
  WheelGeometry wheels;
  EXPECT_TRUE(Read("vehicle:\n  kind: mecanum\n  mecanum_wheel_radius_mm: 50.8\n  track_width_mm: 560\n"
                   "  wheelbase_mm: 480\n", &wheels, false)
                  .empty());
  EXPECT_EQ(wheels.kind, DriveKind::kMecanum);
  EXPECT_EQ(wheels.mecanum_wheel_radius_mm, 50.8);
  EXPECT_EQ(wheels.track_width_mm, 560.0);
  EXPECT_EQ(wheels.wheelbase_mm, 480.0);
  wheels = {};
  EXPECT_THAT(Read("vehicle:\n  kind: mecanum\n  steering_offset_deg: 1\n", &wheels, false),
              ElementsAre(HasSubstr("steering_offset_deg")));
  wheels = {};
  EXPECT_THAT(Read("vehicle:\n  kind: mecanum\n  wheelbase_mm: 0\n", &wheels, false),
              ElementsAre(HasSubstr("wheelbase_mm: must be > 0 mm")));
  wheels = {};
  const auto missing = Read("vehicle:\n  kind: mecanum\n", &wheels, true);
  ASSERT_EQ(missing.size(), 4u);
  EXPECT_THAT(missing[0], HasSubstr("vehicle.mecanum_wheel_radius_mm: missing required key"));
}

}  // namespace
}  // namespace mosaicloc::core

namespace mosaicloc::core {
namespace {

TEST(WheelGeometry, EachKindReadsItsOwnCountersInTheRegistersOrder) {
  EncoderCounts counts;
  counts.left_ticks = 1;
  counts.right_ticks = 2;
  counts.drive_ticks = 3;
  counts.steering_ticks = 4;
  counts.rear_left_ticks = 5;
  counts.rear_right_ticks = 6;
  EXPECT_EQ(CountersOf(DriveKind::kDifferential, counts), (std::vector<std::int32_t>{1, 2}));
  EXPECT_EQ(CountersOf(DriveKind::kTricycle, counts), (std::vector<std::int32_t>{3, 4}));
  EXPECT_EQ(CountersOf(DriveKind::kMecanum, counts), (std::vector<std::int32_t>{1, 2, 5, 6}));
}

}  // namespace
}  // namespace mosaicloc::core
