#include "mosaicloc/runtime/replay.hpp"

#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/runtime/map_session.hpp"
#include "straight_drive_replay.hpp"

namespace mosaicloc::runtime {
namespace {

using ReplayTest = StraightDriveReplay;

TEST_F(ReplayTest, MosaicLocalizesEveryFrameWithoutAWrongFix) {
  std::vector<double> progress;
  const ReplaySummary summary =
      Replay(Options(ReplayMode::kMosaic, "mosaic"), [&progress](double f) { progress.push_back(f); });
  const dataset::Metrics& m = summary.metrics;
  ExpectHeld(m, 0.98, 0.02, 0.1);
  ASSERT_TRUE(m.frames);
  EXPECT_GT(summary.tiles_loaded, 0);
  EXPECT_NEAR(summary.wheel_scale_error.x(), 0.02, 0.01) << "the filter learns the wheels' scale error";
  const std::vector<dataset::FrameReport> rows = Fixes(summary);
  EXPECT_EQ(static_cast<std::int64_t>(rows.size()), *m.frames) << "a row per frame";
  ASSERT_FALSE(progress.empty());
  EXPECT_LE(progress.back(), 1.0);
  for (const char* file : {"estimate.tum", "metrics.json", "trajectory.png", "map_state.png", "map_quality.png",
                           "timelines.png", "index.html"}) {
    EXPECT_TRUE(std::filesystem::exists(summary.report / file)) << file;
  }
  // The figures that need no truth: the states, and a filter whose covariance does not
  // understate its errors.
  EXPECT_EQ(m.frames_by_state.at("tracking") + (m.frames_by_state.count("degraded") ? m.frames_by_state.at("degraded") : 0),
            *m.frames);
  ASSERT_TRUE(m.nis_inside_95_share && m.estimate_path_length_m);
  EXPECT_GE(*m.nis_inside_95_share, 0.9);
  EXPECT_NEAR(*m.estimate_path_length_m, *m.path_length_m, 0.01 * *m.path_length_m);
}

// The camera 3 mm higher than when the map was made: the localizer finds the scale at the
// first fix and holds the floor as at the mapped height (a rigid solve loses such a view:
// Tracker.EstimatesTheImageScaleOfAHigherCamera).
TEST_F(ReplayTest, AHigherCameraIsFollowedByTheImageScale) {
  // The fixture's drive, again, from 3 mm (1.5 %) higher than the map was made at.
  sim::SimulatorOptions drive = Run(true);
  drive.seed = 7;
  drive.height_offset_mm = 3.0;
  sim::Simulate(drive, scratch_->path() / "higher", false);
  ReplayOptions options = Options(ReplayMode::kMosaic, "higher");
  options.dataset = scratch_->path() / "higher";
  const ReplaySummary summary = Replay(options);
  const dataset::Metrics& m = summary.metrics;
  ExpectHeld(m, 0.98, 0.02, 0.1);
  for (const dataset::FrameReport& row : Fixes(summary)) {
    if (row.fixed) {
      EXPECT_NEAR(row.scale * 200.0, 203.0, 0.05) << "the height, mm";
    }
  }
}

TEST_F(ReplayTest, PrefetchingChangesWhereTilesLoadNotTheEstimate) {
  const ReplaySummary plain = Replay(Options(ReplayMode::kMosaic, "plain"));
  ReplayOptions options = Options(ReplayMode::kMosaic, "prefetch");
  options.prefetch = true;
  const ReplaySummary prefetched = Replay(options);
  EXPECT_EQ(test::ReadFile(plain.report / "fixes.csv"), test::ReadFile(prefetched.report / "fixes.csv"));
  EXPECT_EQ(test::ReadFile(plain.report / "estimate.tum"), test::ReadFile(prefetched.report / "estimate.tum"));
  options.settings.prefetch_horizon_s = 0.0;
  EXPECT_THROW(Replay(options), core::Error);
}

TEST_F(ReplayTest, BaselinesMakeNoMapFix) {
  const ReplaySummary dead = Replay(Options(ReplayMode::kDeadReckoning, "dead"));
  ASSERT_TRUE(dead.metrics.fixes && dead.metrics.position_rms_mm);
  EXPECT_EQ(*dead.metrics.fixes, 0);
  EXPECT_GT(*dead.metrics.position_rms_mm, 1.0) << "2 % wheel error over 1.5 m";
  for (const dataset::FrameReport& row : Fixes(dead)) {
    EXPECT_EQ(row.status, 0);
    EXPECT_EQ(row.reason, "dead-reckoning");
  }
  const ReplaySummary vo = Replay(Options(ReplayMode::kVisualOdometry, "vo"));
  ASSERT_TRUE(vo.metrics.fix_rate);
  EXPECT_GE(*vo.metrics.fix_rate, 0.9) << "consecutive frames overlap at 1.2 m/s";
}

TEST_F(ReplayTest, AStartOffTheMapRelocalizesOnlyWhenAsked) {
  ReplayOptions options = Options(ReplayMode::kMosaic, "off");
  options.start_offset = core::Pose2(0.0, 300.0, 0.0);
  const ReplaySummary stays = Replay(options);
  EXPECT_EQ(*stays.metrics.fixes, 0);
  EXPECT_EQ(*stays.metrics.off_map_frames, *stays.metrics.frames) << "the prior says off the map";
  options.out = scratch_->path() / "asked";
  options.relocalize = true;
  const ReplaySummary asked = Replay(options);
  EXPECT_GE(*asked.metrics.fix_rate, 0.95);
  EXPECT_EQ(*asked.metrics.wrong_fixes, 0);
  EXPECT_EQ(asked.relocalizations, 1);
}

TEST(MapSession, RefusesAMapOfAnotherResolutionNamingIt) {
  test::ScratchDir scratch;
  mosaic::MapGrid grid;
  grid.mm_per_px = 0.5;
  mosaic::TileStore::Create(scratch.path() / "coarse.mosaic", grid);
  MapSessionOptions options;
  options.camera_mm_per_px = 0.25;
  try {
    MapSession session(scratch.path() / "coarse.mosaic", options);
    ADD_FAILURE() << "no error";
  } catch (const core::Error& error) {
    EXPECT_EQ(error.kind(), core::ErrorKind::kInvalidInput);
    EXPECT_NE(std::string(error.what()).find("coarse.mosaic: map resolution 0.5 mm/px differs from the camera's 0.25"),
              std::string::npos)
        << error.what();
  }
}

}  // namespace
}  // namespace mosaicloc::runtime
