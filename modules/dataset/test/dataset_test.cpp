#include "mosaicloc/dataset/dataset.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::dataset {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

DatasetInfo SmallInfo() {
  DatasetInfo info;
  info.camera.width_px = 32;
  info.camera.height_px = 24;
  info.camera.mm_per_px = 0.5;
  info.camera.vehicle_from_camera = core::Pose2(200.0, -5.0, 0.01);
  info.vehicle.track_width_mm = 480.0;
  info.provenance["source"] = "test";
  return info;
}

core::Timestamp Ms(std::int64_t ms) { return core::Timestamp::FromNanoseconds(ms * 1'000'000); }

cv::Mat Image(int value) { return cv::Mat(24, 32, CV_8UC1, cv::Scalar(value)); }

void WriteSmall(const fs::path& dir) {
  DatasetWriter writer(dir, SmallInfo(), false);
  for (int i = 0; i < 3; ++i) writer.AddFrame(Ms(33 * i), Image(10 * i));
  for (int i = 0; i < 10; ++i) {
    // Counters that pass the int32 maximum, as a PLC's do.
    writer.AddEncoderSample(
        {Ms(10 * i), {static_cast<std::int32_t>(2147483600u + 10u * static_cast<unsigned>(i)), -5 * i}});
  }
  writer.SetGroundTruth({{Ms(0), core::Pose2(0, 0, 0)}, {Ms(66), core::Pose2(66, 0, 0)}});
  writer.Commit();
}

// Throws the reader's error for `dir` fully read, or fails the test if none.
std::string ReadError(const fs::path& dir) {
  try {
    DatasetReader(dir).Validate();
  } catch (const core::Error& e) {
    EXPECT_EQ(e.kind(), core::ErrorKind::kInvalidInput);
    return e.what();
  }
  ADD_FAILURE() << "no error reading " << dir;
  return "";
}

TEST(Dataset, RoundTrip) {
  test::ScratchDir scratch;
  const fs::path dir = scratch / "ds";
  WriteSmall(dir);
  const DatasetReader reader(dir);
  EXPECT_EQ(reader.info().camera.width_px, 32);
  EXPECT_DOUBLE_EQ(reader.info().camera.vehicle_from_camera.yaw_rad(), 0.01);
  EXPECT_DOUBLE_EQ(reader.info().vehicle.track_width_mm, 480.0);
  EXPECT_EQ(reader.info().provenance.at("source"), "test");

  auto frames = reader.Frames();
  for (int i = 0; i < 3; ++i) {
    const auto frame = frames.Next();
    ASSERT_TRUE(frame.has_value());
    EXPECT_EQ(frame->time, Ms(33 * i));
    EXPECT_EQ(frame->image.at<std::uint8_t>(5, 5), 10 * i);
  }
  EXPECT_FALSE(frames.Next().has_value());

  auto encoders = reader.Encoders();
  std::vector<EncoderSample> samples;
  while (const auto sample = encoders.Next()) samples.push_back(*sample);
  ASSERT_EQ(samples.size(), 10u);
  EXPECT_EQ(samples[9].counts.left_ticks, -2147483606);  // 2147483690 wrapped
  EXPECT_EQ(samples[9].counts.right_ticks, -45);

  const auto summary = reader.Validate();
  EXPECT_EQ(summary.frames, 3);
  EXPECT_EQ(summary.encoder_samples, 10);
  EXPECT_EQ(summary.groundtruth_poses, 2);
  EXPECT_NEAR(summary.duration_s, 0.066, 1e-12);
  EXPECT_EQ(summary.Describe(), "valid: 3 frames, 10 encoder samples, 2 ground-truth poses, 0.07 s");
}

// A tricycle's dataset names its kind and keys, and its encoder file its two counters; a
// differential drive's file under a tricycle's header is an error at the header.
TEST(Dataset, TricycleRoundTrip) {
  test::ScratchDir scratch;
  DatasetInfo info = SmallInfo();
  info.vehicle.kind = core::DriveKind::kTricycle;
  info.vehicle.wheelbase_mm = 1350.0;
  info.vehicle.steering_offset_deg = -0.25;
  {
    DatasetWriter writer(scratch / "ds", info, false);
    writer.AddFrame(Ms(0), Image(1));
    EncoderSample sample;
    sample.time = Ms(0);
    sample.counts.drive_ticks = 2147483600;
    sample.counts.steering_ticks = -1234;
    writer.AddEncoderSample(sample);
    writer.Commit();
  }
  const DatasetReader reader(scratch / "ds");
  EXPECT_EQ(reader.info().vehicle.kind, core::DriveKind::kTricycle);
  EXPECT_EQ(reader.info().vehicle.wheelbase_mm, 1350.0);
  EXPECT_EQ(reader.info().vehicle.steering_offset_deg, -0.25);
  auto encoders = reader.Encoders();
  const auto read = encoders.Next();
  ASSERT_TRUE(read.has_value());
  EXPECT_EQ(read->counts.drive_ticks, 2147483600);
  EXPECT_EQ(read->counts.steering_ticks, -1234);
  EXPECT_EQ(read->counts.left_ticks, 0);
  test::WriteFile(scratch / "ds/encoders/data.csv", "#timestamp_ns,left_ticks,right_ticks\n0,1,2\n");
  EXPECT_THAT(ReadError(scratch / "ds"), HasSubstr("encoders/data.csv"));
}

TEST(Dataset, MecanumRoundTrip) {
  test::ScratchDir scratch;
  DatasetInfo info = SmallInfo();
  info.vehicle.kind = core::DriveKind::kMecanum;
  info.vehicle.mecanum_wheel_radius_mm = 50.8;
  info.vehicle.track_width_mm = 560.0;
  info.vehicle.wheelbase_mm = 480.0;
  {
    DatasetWriter writer(scratch / "ds", info, false);
    writer.AddFrame(Ms(0), Image(1));
    EncoderSample sample;
    sample.time = Ms(0);
    sample.counts.left_ticks = 1;
    sample.counts.right_ticks = -2;
    sample.counts.rear_left_ticks = 2147483600;
    sample.counts.rear_right_ticks = -2147483600;
    writer.AddEncoderSample(sample);
    writer.Commit();
  }
  const DatasetReader reader(scratch / "ds");
  EXPECT_EQ(reader.info().vehicle.kind, core::DriveKind::kMecanum);
  EXPECT_EQ(reader.info().vehicle.mecanum_wheel_radius_mm, 50.8);
  EXPECT_EQ(reader.info().vehicle.track_width_mm, 560.0);
  EXPECT_EQ(reader.info().vehicle.wheelbase_mm, 480.0);
  EXPECT_EQ(test::ReadFile(scratch / "ds/encoders/data.csv"),
            "#timestamp_ns,front_left_ticks,front_right_ticks,rear_left_ticks,rear_right_ticks\n"
            "0,1,-2,2147483600,-2147483600\n");
  auto encoders = reader.Encoders();
  const auto read = encoders.Next();
  ASSERT_TRUE(read.has_value());
  EXPECT_EQ(read->counts, (core::EncoderCounts{1, -2, 0, 0, 2147483600, -2147483600}));
  // A row with a differential drive's two counters, and a differential drive's header.
  test::WriteFile(scratch / "ds/encoders/data.csv",
                  "#timestamp_ns,front_left_ticks,front_right_ticks,rear_left_ticks,rear_right_ticks\n0,1,2\n");
  EXPECT_THAT(ReadError(scratch / "ds"), HasSubstr("data.csv:2: expected 5 fields"));
  test::WriteFile(scratch / "ds/encoders/data.csv", "#timestamp_ns,left_ticks,right_ticks\n0,1,2\n");
  EXPECT_THAT(ReadError(scratch / "ds"), HasSubstr("names a differential's counters"));
}

TEST(Dataset, UncommittedWriterLeavesNothing) {
  test::ScratchDir scratch;
  {
    DatasetWriter writer(scratch / "ds", SmallInfo(), false);
    writer.AddFrame(Ms(0), Image(1));
  }
  EXPECT_TRUE(fs::is_empty(scratch.path()));
}

TEST(Dataset, AWriterKilledOutrightLeavesNothingTheNextOneKeeps) {
  test::ScratchDir scratch;
  // A writer of "ds" killed by SIGKILL: its process is gone, its staging folder left.
  const pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  ASSERT_GT(child, 0);
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  const fs::path dead = scratch / (".ds.partial-" + std::to_string(child));
  const fs::path alive = scratch / (".ds.partial-" + std::to_string(::getppid()));  // another writer, still running
  fs::create_directories(dead / "cam0");
  fs::create_directories(alive / "cam0");
  {
    DatasetWriter writer(scratch / "ds", SmallInfo(), false);
    writer.AddFrame(Ms(0), Image(1));
    writer.Commit();
  }
  EXPECT_FALSE(fs::exists(dead));
  EXPECT_TRUE(fs::exists(alive));
  EXPECT_TRUE(fs::exists(scratch / "ds" / "dataset.yaml"));
}

TEST(Dataset, ExtraFilesAppearOnCommitAndStayInside) {
  test::ScratchDir scratch;
  {
    DatasetWriter writer(scratch / "ds", SmallInfo(), false);
    writer.AddFrame(Ms(0), Image(1));
    writer.AddFile("fixes/data.csv", "#timestamp_ns,x_mm\n1,2\n");
    EXPECT_THROW(writer.AddFile("../outside.csv", "x"), core::Error);
    EXPECT_THROW(writer.AddFile("/tmp/outside.csv", "x"), core::Error);
    EXPECT_FALSE(fs::exists(scratch / "ds"));
    writer.Commit();
  }
  EXPECT_EQ(test::ReadFile(scratch / "ds" / "fixes" / "data.csv"), "#timestamp_ns,x_mm\n1,2\n");
  EXPECT_FALSE(fs::exists(scratch / "outside.csv"));
}

TEST(Dataset, RefusesToOverwriteUnlessAskedAndReplacesWhole) {
  test::ScratchDir scratch;
  WriteSmall(scratch / "ds");
  EXPECT_THROW(DatasetWriter(scratch / "ds", SmallInfo(), false), core::Error);
  {
    DatasetWriter writer(scratch / "ds", SmallInfo(), true);
    writer.AddFrame(Ms(5), Image(7));
    // not committed: the old dataset must survive untouched
  }
  EXPECT_EQ(DatasetReader(scratch / "ds").Validate().frames, 3);
  {
    DatasetWriter writer(scratch / "ds", SmallInfo(), true);
    writer.AddFrame(Ms(5), Image(7));
    writer.Commit();
  }
  EXPECT_EQ(DatasetReader(scratch / "ds").Validate().frames, 1);
}

TEST(Dataset, WriterRejectsBadFrames) {
  test::ScratchDir scratch;
  DatasetWriter writer(scratch / "ds", SmallInfo(), false);
  writer.AddFrame(Ms(10), Image(1));
  EXPECT_THROW(writer.AddFrame(Ms(10), Image(1)), core::Error);
  EXPECT_THROW(writer.AddFrame(Ms(20), cv::Mat(10, 10, CV_8UC1)), core::Error);
}

TEST(Dataset, MissingImageIsNamedWithItsLine) {
  test::ScratchDir scratch;
  const fs::path dir = scratch / "ds";
  WriteSmall(dir);
  fs::remove(dir / "cam0/data/33000000.png");
  const std::string error = ReadError(dir);
  EXPECT_THAT(error, HasSubstr("cam0/data.csv:3: image"));
  EXPECT_THAT(error, HasSubstr("33000000.png is missing"));
}

TEST(Dataset, MalformedCsvLine) {
  test::ScratchDir scratch;
  const fs::path dir = scratch / "ds";
  WriteSmall(dir);
  std::string csv = test::ReadFile(dir / "encoders/data.csv");
  csv += "120000000,12x,4\n";
  test::WriteFile(dir / "encoders/data.csv", csv);
  EXPECT_THAT(ReadError(dir),
              HasSubstr("encoders/data.csv:12: left_ticks '12x' is not an int32 counter value"));

  test::WriteFile(dir / "encoders/data.csv", "#timestamp_ns,left_ticks,right_ticks\n1,2\n");
  EXPECT_THAT(ReadError(dir), HasSubstr("encoders/data.csv:2: expected 3 fields"));

  test::WriteFile(dir / "encoders/data.csv",
                  "#timestamp_ns,left_ticks,right_ticks\n1,2,3000000000\n");
  EXPECT_THAT(ReadError(dir), HasSubstr("right_ticks '3000000000' is not an int32"));
}

// A row recorded twice or out of order is a recording's fault, not an error: it is skipped
// (counted, and warned about once), and every stream sees times that increase.
TEST(Dataset, RowsNotAfterTheRowBeforeAreSkipped) {
  test::ScratchDir scratch;
  const fs::path dir = scratch / "ds";
  WriteSmall(dir);
  test::WriteFile(dir / "cam0/data.csv",
                  "#timestamp_ns,filename\n0,0.png\n66000000,66000000.png\n33000000,33000000.png\n"
                  "66000000,66000000.png\n");
  test::WriteFile(dir / "encoders/data.csv",
                  "#timestamp_ns,left_ticks,right_ticks\n0,1,1\n20000000,2,2\n10000000,3,3\n30000000,4,4\n");
  const DatasetReader reader(dir);
  EXPECT_EQ(reader.skipped_frames(), 2);
  EXPECT_EQ(reader.skipped_encoder_samples(), 1);
  std::vector<std::int64_t> frame_ns;
  for (auto frames = reader.Frames(); const auto frame = frames.Next();) frame_ns.push_back(frame->time.nanoseconds());
  EXPECT_THAT(frame_ns, testing::ElementsAre(0, 66000000));
  std::vector<std::int32_t> ticks;
  for (auto encoders = reader.Encoders(); const auto sample = encoders.Next();) ticks.push_back(sample->counts.left_ticks);
  EXPECT_THAT(ticks, testing::ElementsAre(1, 2, 4));
  const DatasetReader::Summary summary = reader.Validate();
  EXPECT_EQ(summary.frames, 2);
  EXPECT_EQ(summary.skipped_frames, 2);
  EXPECT_EQ(summary.skipped_encoder_samples, 1);
  EXPECT_THAT(summary.Describe(), HasSubstr("\n  skipped, not after the row before in time: 2 frames, 1 encoder samples"));

  // A bad time is still an error, named by file and line.
  test::WriteFile(dir / "cam0/data.csv", "#timestamp_ns,filename\n0,0.png\nsoon,66000000.png\n");
  EXPECT_THAT(ReadError(dir), HasSubstr("cam0/data.csv:3: timestamp_ns 'soon' is not an integer"));
}

TEST(Dataset, ImageOfWrongSizeOrPathEscape) {
  test::ScratchDir scratch;
  const fs::path dir = scratch / "ds";
  WriteSmall(dir);
  test::WriteFile(dir / "cam0/data.csv", "#timestamp_ns,filename\n0,../../dataset.yaml\n");
  EXPECT_THAT(ReadError(dir), HasSubstr("must be a plain file name"));
  test::WriteFile(dir / "cam0/data.csv", "#timestamp_ns,filename\n0,0.png\n");
  test::WriteFile(dir / "cam0/data/0.png", "not a png");
  EXPECT_THAT(ReadError(dir), HasSubstr("cannot be decoded"));
}

TEST(Dataset, YamlTypoIsRejected) {
  test::ScratchDir scratch;
  const fs::path dir = scratch / "ds";
  WriteSmall(dir);
  std::string yaml = test::ReadFile(dir / "dataset.yaml");
  const auto at = yaml.find("track_width_mm");
  ASSERT_NE(at, std::string::npos);
  yaml.replace(at, 14, "track_widht_mm");
  test::WriteFile(dir / "dataset.yaml", yaml);
  const std::string error = ReadError(dir);
  EXPECT_THAT(error, HasSubstr("vehicle.track_width_mm: missing required key"));
  EXPECT_THAT(error,
              HasSubstr("vehicle.track_widht_mm: unknown key (did you mean 'track_width_mm'?)"));
  EXPECT_THAT(error, HasSubstr("dataset.yaml:"));
}

// Provenance is free text, but its keys are names: a mapping or a list as a key is reported
// with its line, never an exception of the YAML library.
TEST(Dataset, ProvenanceKeysMustBeNames) {
  test::ScratchDir scratch;
  const fs::path dir = scratch / "ds";
  WriteSmall(dir);
  std::string yaml = test::ReadFile(dir / "dataset.yaml");
  const auto at = yaml.find("provenance:");
  ASSERT_NE(at, std::string::npos);
  yaml.insert(yaml.find('\n', at) + 1, "  ? [a, b]\n  : 1\n");
  test::WriteFile(dir / "dataset.yaml", yaml);
  const std::string error = ReadError(dir);
  EXPECT_THAT(error, HasSubstr("provenance: a key must be a plain name"));
}

TEST(Dataset, MissingDirectoryAndFiles) {
  test::ScratchDir scratch;
  EXPECT_THAT(ReadError(scratch / "nope"), HasSubstr("no such dataset directory"));
  WriteSmall(scratch / "ds");
  fs::remove(scratch / "ds/encoders/data.csv");
  EXPECT_THAT(ReadError(scratch / "ds"), HasSubstr("encoders/data.csv: missing or unreadable"));
}

}  // namespace
}  // namespace mosaicloc::dataset
