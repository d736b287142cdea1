#include "mosaicloc/sim/simulator.hpp"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::sim {
namespace {

namespace fs = std::filesystem;

SimulatorOptions Small() {
  SimulatorOptions options;
  options.camera = camera::IdealCameraOptions{160, 120, 0.25};
  options.frames = 24;
  options.route.name = "loop";
  options.route.speed_mps = 2.0;
  options.drop_probability = 0.1;
  return options;
}

// Every file below `dir`, relative path -> content.
std::map<std::string, std::string> Files(const fs::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& entry : fs::recursive_directory_iterator(dir)) {
    if (entry.is_regular_file()) files[fs::relative(entry.path(), dir).string()] = test::ReadFile(entry.path());
  }
  return files;
}

TEST(Simulate, WritesADatasetTheReaderValidates) {
  test::ScratchDir scratch;
  const SimulationSummary summary = Simulate(Small(), scratch / "ds", false);
  EXPECT_EQ(summary.frames_written + summary.frames_dropped, 24);
  const dataset::DatasetReader reader(scratch / "ds");
  const auto validated = reader.Validate();
  EXPECT_EQ(validated.frames, summary.frames_written);
  EXPECT_EQ(validated.groundtruth_poses, summary.frames_written);
  EXPECT_EQ(validated.encoder_samples, summary.encoder_samples);
  EXPECT_EQ(reader.info().camera.width_px, 160);
  EXPECT_EQ(reader.info().provenance.at("route"), "loop");
}

// A live source plays the drive Simulate writes: the same frames at the same instants, the
// same encoder samples and the same truth, computed as they are due.
TEST(PlannedDrive, PlaysWhatSimulateWrites) {
  test::ScratchDir scratch;
  SimulatorOptions options = Small();
  options.encoders.nominal.kind = core::DriveKind::kTricycle;  // the steering's backlash carries over samples
  options.encoders.steering_backlash_deg = 0.2;
  options.route.curvature_transition_m = 0.5;
  Simulate(options, scratch / "ds", false);
  const dataset::DatasetReader reader(scratch / "ds");
  const PlannedDrive plan(options);
  EXPECT_EQ(plan.info().provenance, reader.info().provenance);
  EXPECT_EQ(plan.info().vehicle.kind, core::DriveKind::kTricycle);
  std::size_t k = 0;
  auto frames = reader.Frames();
  while (const auto frame = frames.Next()) {
    ASSERT_LT(k, plan.capture_s().size());
    EXPECT_EQ(frame->time, core::Timestamp::FromSeconds(plan.capture_s()[k]));
    const cv::Mat rendered = plan.RenderFrame(k);
    ASSERT_EQ(rendered.size(), frame->image.size());
    EXPECT_EQ(cv::norm(rendered, frame->image, cv::NORM_INF), 0.0) << "frame " << k;
    EXPECT_EQ(Distance(plan.TruthAt(plan.capture_s()[k]), dataset::PoseAt(reader.GroundTruth(), frame->time,
                                                                          std::chrono::milliseconds(1))
                                                              .value()),
              0.0);
    ++k;
  }
  EXPECT_EQ(k, plan.capture_s().size());
  auto recorded = reader.Encoders();
  PlannedDrive::EncoderStream played = plan.Encoders();
  std::int64_t samples = 0;
  while (const auto sample = recorded.Next()) {
    const auto computed = played.Next();
    ASSERT_TRUE(computed) << "sample " << samples;
    EXPECT_EQ(computed->time, sample->time);
    EXPECT_EQ(computed->counts, sample->counts) << "sample " << samples;
    ++samples;
  }
  EXPECT_FALSE(played.Next()) << "no sample past the recording's last";
  EXPECT_GT(samples, 50);
}

TEST(Simulate, SameSeedGivesIdenticalBytesWhateverTheThreads) {
  test::ScratchDir scratch;
  SimulatorOptions options = Small();
  options.threads = 1;
  Simulate(options, scratch / "a", false);
  options.threads = 3;
  Simulate(options, scratch / "b", false);
  options.seed = 2;
  Simulate(options, scratch / "c", false);
  const auto a = Files(scratch / "a");
  EXPECT_EQ(a, Files(scratch / "b"));
  EXPECT_NE(a, Files(scratch / "c"));
}

TEST(Simulate, LapsOverrideFrames) {
  test::ScratchDir scratch;
  SimulatorOptions options = Small();
  options.route.loop_width_m = 0.6;
  options.route.loop_height_m = 0.4;
  options.route.corner_radius_m = 0.1;
  options.route.stop_s = 0.1;
  options.laps = 2;
  options.drop_probability = 0.0;
  const SimulationSummary summary = Simulate(options, scratch / "ds", false);
  EXPECT_NEAR(summary.laps_driven, 2.0, 1e-3);
  EXPECT_NEAR(summary.path_length_m, 2 * summary.lap_length_m, 0.01);
}

TEST(Simulate, BadOptionsAndMissingFloorImageAreRefused) {
  test::ScratchDir scratch;
  SimulatorOptions options = Small();
  options.floor.kind = "image";
  options.floor.image = scratch / "missing.png";
  try {
    Simulate(options, scratch / "ds", false);
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("missing.png"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(scratch / "ds"));
  options = Small();
  options.frame_rate_hz = 0.0;
  EXPECT_THROW(Simulate(options, scratch / "ds", false), core::Error);
}

TEST(Simulate, RealTextureFloor) {
  const auto texture = test::SharedTexture("asphalt_02_2048.jpg");
  if (!texture) GTEST_SKIP() << test::SharedDataMissingMessage();
  test::ScratchDir scratch;
  SimulatorOptions options = Small();
  options.floor.kind = "image";
  options.floor.image = *texture;
  Simulate(options, scratch / "ds", false);
  EXPECT_GT(dataset::DatasetReader(scratch / "ds").Validate().frames, 0);
}

}  // namespace
}  // namespace mosaicloc::sim
