#include "mosaicloc/sim/simulator.hpp"

#include <gtest/gtest.h>

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
