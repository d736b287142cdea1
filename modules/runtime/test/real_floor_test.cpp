// Replays over real floors, simulated end to end as a user would run them: the replay
// tests' straight drive again, with the camera or the floor as real vehicles and floors are
// (a camera whose height and tilt change, a floor that changed since it was mapped). System
// tests on the optimized build: each simulates, maps and replays.
#include <chrono>
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "mosaicloc/runtime/map_jobs.hpp"
#include "straight_drive_replay.hpp"

namespace mosaicloc::runtime {
namespace {

using RealFloorTest = StraightDriveReplay;

// The fixture's drive from a vehicle whose body pitches by half a degree per m/s^2 about an
// axis 100 mm over the floor: starting and braking (1 m/s^2) move the image centre 0.9 mm
// against the camera's mounting point. Registered without the tilt, the fixes carry that
// lever; with the tilt estimated from twelve templates and the pivot's height known, it comes
// out of them.
TEST_F(RealFloorTest, ATiltingBodysLeverIsTakenOutOfTheFixes) {
  sim::SimulatorOptions drive = Run(true);
  drive.seed = 8;
  drive.suspension.pitch_deg_per_mps2 = 0.5;
  drive.suspension.pivot_height_mm = 100.0;
  sim::Simulate(drive, scratch_->path() / "tilting", false);
  ReplayOptions options = Options(ReplayMode::kMosaic, "tilting-untilted", "tilting");
  options.settings.localizer.tracker.templates.count = 12;
  const ReplaySummary untilted = Replay(options);
  ASSERT_TRUE(untilted.metrics.position_max_mm && untilted.metrics.wrong_fixes);
  EXPECT_GT(*untilted.metrics.position_max_mm, 0.3) << "the lever, not taken out";
  EXPECT_EQ(*untilted.metrics.wrong_fixes, 0);

  options.out = scratch_->path() / "tilting-tilted";
  options.settings.localizer.tracker.solver.estimate_tilt = true;
  options.settings.localizer.tilt_pivot_height_mm = 100.0;
  const ReplaySummary tilted = Replay(options);
  const dataset::Metrics& m = tilted.metrics;
  ExpectHeld(m, 0.999, 0.02, 0.1);
  ASSERT_TRUE(m.height_error_rms_mm) << "the simulator recorded the camera's height";
  EXPECT_LT(*m.height_error_rms_mm, 0.05);
  EXPECT_TRUE(std::filesystem::exists(tilted.report / "height.png"));
}

// The same body maps the floor too: its mapping run (0.5 m/s) starts and stops at 1 m/s^2, so
// while it does its camera looks at floor 0.9 mm beside its mounting point. Painted at the
// mounting point's true poses the map holds that floor 0.9 mm out of place, and the drive's
// fixes, lever and all taken out, land there; painted as the camera saw the floor (map build at
// the ground truth, which reads the view the simulator recorded: where the optical axis met the
// floor, the height and the slant), the map is where the floor is.
TEST_F(RealFloorTest, AMapIsPaintedAtTheGroundTruthWhereItsCameraLooked) {
  sim::SimulatorOptions mapping = Run(false);
  mapping.suspension.pitch_deg_per_mps2 = 0.5;
  mapping.suspension.pivot_height_mm = 100.0;
  sim::Simulate(mapping, scratch_->path() / "tilting-map-run", false);
  sim::SimulatorOptions drive = Run(true);
  drive.seed = 10;
  drive.suspension = mapping.suspension;
  sim::Simulate(drive, scratch_->path() / "tilting-both", false);

  ReplayOptions options = Options(ReplayMode::kMosaic, "looked-at-mount", "tilting-both");
  options.settings.localizer.tracker.templates.count = 12;
  options.settings.localizer.tracker.solver.estimate_tilt = true;
  options.settings.localizer.tilt_pivot_height_mm = 100.0;
  options.map = scratch_->path() / "tilting-mount.mosaic";
  PaintAtTruth(scratch_->path() / "tilting-map-run", options.map);
  const ReplaySummary at_mount = Replay(options);
  ASSERT_TRUE(at_mount.metrics.position_max_mm && at_mount.metrics.position_rms_mm);
  std::printf("painted at the mounting point: position %.4f / %.4f mm RMS / max\n", *at_mount.metrics.position_rms_mm,
              *at_mount.metrics.position_max_mm);
  EXPECT_GT(*at_mount.metrics.position_max_mm, 0.3) << "the mapping run's lever, painted into the map";

  MapBuildOptions build;
  build.dataset = scratch_->path() / "tilting-map-run";
  build.out = scratch_->path() / "tilting-view.mosaic";
  build.poses = "groundtruth";
  BuildMap(build);
  options.map = build.out;
  options.out = scratch_->path() / "looked-at-view";
  ExpectHeld(Replay(options).metrics, 0.999, 0.02, 0.1);
}

// The fixture's drive over a floor that is no longer flat (1 mm RMS in waves of 1 to 2 m, felt
// through the wheels and the caster) from a camera 2 mm higher than the map was made at: the
// height and the tilt change from frame to frame. The localizer follows the height; the
// tilt's keystone stays within the solver's tolerance.
TEST_F(RealFloorTest, AnUnevenFloorUnderAHigherCameraIsFollowed) {
  sim::SimulatorOptions drive = Run(true);
  drive.seed = 9;
  drive.floor.unevenness_mm = 1.0;
  drive.floor.unevenness_wavelength_m = 1.0;
  drive.height_offset_mm = 2.0;
  sim::Simulate(drive, scratch_->path() / "uneven", false);
  ReplayOptions options = Options(ReplayMode::kMosaic, "uneven-report", "uneven");
  const ReplaySummary summary = Replay(options);
  const dataset::Metrics& m = summary.metrics;
  ExpectHeld(m, 0.999, 0.02, 0.1);
  ASSERT_TRUE(m.height_error_rms_mm);
  EXPECT_LT(*m.height_error_rms_mm, 0.05);
}

// The fixture's drive over the floor as it looks months after it was mapped: grime over 40 %
// of it, stains, tyre marks of a narrow vehicle under the camera, a wet patch and a lane line
// across the lane, and a tile replaced by new floor 250 mm square. Outside the tile nearly
// every frame gets a fix; over it there is none, and no fix is wrong anywhere.
TEST_F(RealFloorTest, AChangedFloorGivesNoWrongFix) {
  sim::SimulatorOptions drive = Run(true);
  drive.seed = 10;
  sim::FloorChangeOptions& c = drive.changes;
  c.grime_fraction = 0.4;
  c.stains_per_m2 = 5.0;
  c.tyre_marks = 0.6;
  c.tyre_track_width_mm = 100.0;
  c.wet_x_mm = 500.0;
  c.wet_radius_mm = 150.0;
  c.lane_x0_mm = 900.0;
  c.lane_y0_mm = -300.0;
  c.lane_x1_mm = 900.0;
  c.lane_y1_mm = 300.0;
  c.lane_width_mm = 80.0;
  c.tile_x_mm = 1300.0;
  c.tile_size_mm = 250.0;
  sim::Simulate(drive, scratch_->path() / "changed", false);
  ReplayOptions options = Options(ReplayMode::kMosaic, "changed-report", "changed");
  const ReplaySummary summary = Replay(options);
  const dataset::Metrics& m = summary.metrics;
  ASSERT_TRUE(m.wrong_fixes && m.lock_losses);
  EXPECT_EQ(*m.wrong_fixes, 0);
  EXPECT_EQ(*m.lock_losses, 0);
  // The fix rate of the frames whose view (160 x 120 mm, 200 mm ahead of the vehicle) stays
  // clear of the tile.
  const dataset::Trajectory truth = dataset::DatasetReader(options.dataset).GroundTruth();
  std::int64_t clear = 0, clear_fixed = 0, over = 0, over_fixed = 0;
  for (const dataset::FrameReport& row : Fixes(summary)) {
    const auto pose = dataset::PoseAt(truth, row.time, std::chrono::milliseconds(100));
    ASSERT_TRUE(pose);
    const Eigen::Vector2d camera = *pose * Eigen::Vector2d(200.0, 0.0);
    const bool touches = std::abs(camera.x() - c.tile_x_mm) < 0.5 * c.tile_size_mm + 100.0 &&
                         std::abs(camera.y() - c.tile_y_mm) < 0.5 * c.tile_size_mm + 100.0;
    (touches ? over : clear) += 1;
    (touches ? over_fixed : clear_fixed) += row.fixed ? 1 : 0;
  }
  ASSERT_GT(clear, 0);
  ASSERT_GT(over, 0);
  std::printf("clear of the tile: %lld of %lld frames fixed; over it: %lld of %lld\n", static_cast<long long>(clear_fixed),
              static_cast<long long>(clear), static_cast<long long>(over_fixed), static_cast<long long>(over));
  EXPECT_GE(static_cast<double>(clear_fixed) / static_cast<double>(clear), 0.995);
  EXPECT_LT(over_fixed, over) << "the new tile is not the mapped floor";
}

// The fixture's straight over a floor with relief (its darkest parts 1 mm below the tops)
// under a ring light of eight LEDs 50 mm around the lens, mapped at 1 m/s and driven with 15 %
// less light. The default tracker is biased by the relief's parallax and shading and its fixes'
// covariance does not show it, so the filter's gate refuses some; with the fixes' covariance
// from their templates' scatter the localizer holds every frame. Neither gives a wrong fix.
TEST_F(RealFloorTest, AFloorWithReliefUnderARingLightGivesNoWrongFix) {
  sim::SimulatorOptions map_run = Run(false);
  map_run.route.speed_mps = 1.0;  // half the frames of the fixture's map: a relief frame costs 11 flat ones
  map_run.relief.depth_mm = 1.0;
  map_run.light.sources = 8;
  sim::Simulate(map_run, scratch_->path() / "relief-map-run", false);
  PaintAtTruth(scratch_->path() / "relief-map-run", scratch_->path() / "relief.mosaic");
  sim::SimulatorOptions drive = Run(true);
  drive.relief = map_run.relief;
  drive.light = map_run.light;
  drive.light.ring_gain = 0.85;
  sim::Simulate(drive, scratch_->path() / "relief", false);

  ReplayOptions options = Options(ReplayMode::kMosaic, "relief-default", "relief");
  options.map = scratch_->path() / "relief.mosaic";
  const dataset::Metrics plain = Replay(options).metrics;
  ASSERT_TRUE(plain.wrong_fixes && plain.lock_losses);
  EXPECT_EQ(*plain.wrong_fixes, 0);
  EXPECT_EQ(*plain.lock_losses, 0);

  options.out = scratch_->path() / "relief-posterior";
  options.settings.localizer.tracker.solver.posterior_variance = true;
  const dataset::Metrics posterior = Replay(options).metrics;
  ExpectHeld(posterior, 0.995, 0.03, 0.15);
  std::printf("relief 1 mm: default %.4f fixes, %.4f / %.4f mm RMS / max; posterior variance %.4f, %.4f / %.4f\n",
              *plain.fix_rate, *plain.position_rms_mm, *plain.position_max_mm, *posterior.fix_rate,
              *posterior.position_rms_mm, *posterior.position_max_mm);
}

}  // namespace
}  // namespace mosaicloc::runtime
