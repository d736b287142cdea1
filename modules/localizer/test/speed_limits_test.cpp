#include "mosaicloc/localizer/speed_limits.hpp"

#include <cmath>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

#include "mosaicloc/camera/real_camera.hpp"
#include "mosaicloc/core/error.hpp"

namespace mosaicloc::localizer {
namespace {

// The simulator's camera: 640x480 at 0.25 mm/px, 30 Hz, 100 us, travelling along image right.
TEST(SpeedLimits, NominalSetup) {
  const SpeedLimits limits = AnalyseSpeedLimits(SpeedLimitOptions{});
  EXPECT_NEAR(limits.cycle_s, 1.0 / 30.0, 1e-12);
  EXPECT_NEAR(limits.footprint_along_mm, 160.0, 1e-9);
  EXPECT_NEAR(limits.half_diagonal_px, 400.0, 1e-9);
  EXPECT_NEAR(limits.overlap_limit_mps, 2.4, 1e-9);          // 160 mm * 0.5 * 30 Hz
  EXPECT_NEAR(limits.height_tolerance_mm, 0.25, 1e-12);      // 0.5 px * 200 mm / 400 px
  EXPECT_NEAR(limits.scaled_height_tolerance_mm, 30.0, 1e-12);  // 0.15 * 200 mm
  // 0.5 px * 200 mm / (0.25 mm/px * 400^2 px^2) = 0.0025 rad
  EXPECT_NEAR(limits.rigid_tilt_tolerance_deg, 0.0025 * 180.0 / 3.14159265358979, 1e-9);
  EXPECT_NEAR(limits.tilt_tolerance_deg, 1.5, 1e-12);
  EXPECT_NEAR(limits.tilt_lever_mm_per_deg, 100.0 * 3.14159265358979 / 180.0, 1e-9);
  EXPECT_NEAR(limits.distortion_limit_mps, 3.75, 1e-9);      // 0.25 mm / (0.002 * 1/30 s)
  EXPECT_NEAR(limits.blur_limit_mps, 7.5, 1e-9);             // 3 px * 0.25 mm / 100 us
  EXPECT_NEAR(limits.prediction_limit_mps, 36.0, 1e-9);      // 96 px * 0.25 mm / (0.02 / 30 Hz)
  EXPECT_NEAR(limits.mosaic_limit_mps, 7.5, 1e-9);
  EXPECT_NEAR(limits.step_mm, 240.0, 1e-9);                  // 7.2 m/s / 30 Hz
  EXPECT_NEAR(limits.instability_ratio, 1.5, 1e-12);
  EXPECT_NEAR(limits.blur_px, 2.88, 1e-12);
  EXPECT_NEAR(limits.prediction_error_mm, 4.8, 1e-12);
}

// Joints 2 mm deep under a camera 200 mm up with a 50 mm ring light.
TEST(SpeedLimits, ReliefTerms) {
  EXPECT_EQ(AnalyseSpeedLimits(SpeedLimitOptions{}).relief_distortion_limit_mps, 0.0);  // flat
  SpeedLimitOptions options;
  options.relief_depth_mm = 2.0;
  const SpeedLimits limits = AnalyseSpeedLimits(options);
  EXPECT_NEAR(limits.relief_scale, 2.0 / 202.0, 1e-12);
  EXPECT_NEAR(limits.relief_parallax_px, 400.0 * 2.0 / 202.0, 1e-9);  // 3.96 px at the corner
  EXPECT_NEAR(limits.relief_parallax_mm, 0.25 * 400.0 * 2.0 / 202.0, 1e-9);
  EXPECT_NEAR(limits.relief_shadow_mm, 0.5, 1e-12);  // 2 mm x 50 / 200
  // 0.5 px x 0.25 mm x 202 / (2 mm x 1/30 s) = 378.75 mm/s
  EXPECT_NEAR(limits.relief_distortion_limit_mps, 0.37875, 1e-9);
  // A pinhole check of the parallax: a point d below the top seen at the corner.
  const double corner_mm = 400.0 * 0.25;
  const double seen_at = corner_mm * 200.0 / (200.0 + 2.0);  // where its ray crosses the top surface
  EXPECT_NEAR((corner_mm - seen_at) / 0.25, 400.0 * 2.0 / 202.0, 1e-9);
}

// A camera whose height over the floor wanders by 0.15 mm at 200 mm: each chained step is
// off by 7.5e-4, 2.25 mm over 3 m between loop closures. The simulator's 1 mm RMS floor gives
// that wander, and its one-lap 11 m map with two loop closures is 1.0-1.1 mm RMS off.
TEST(SpeedLimits, MappingOverAnUnevenFloorDriftsBetweenLoops) {
  SpeedLimitOptions options;
  SpeedLimits limits = AnalyseSpeedLimits(options);
  EXPECT_NEAR(limits.mapping_scale_error, 7.5e-4, 1e-12);
  EXPECT_NEAR(limits.mapping_drift_mm, 2.25, 1e-9);
  options.loop_spacing_m = 1.0;
  options.height_variation_mm = 0.0;  // a telecentric lens, or a height measured and taken out
  limits = AnalyseSpeedLimits(options);
  EXPECT_EQ(limits.mapping_drift_mm, 0.0);
  options.loop_spacing_m = 0.0;
  std::string why;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_NE(why.find("loop_spacing_m"), std::string::npos);
}

TEST(SpeedLimits, TravelAlongTheShortSideHalvesLess) {
  SpeedLimitOptions options;
  options.travel_direction_rad = std::numbers::pi / 2.0;  // along image up: 480 px of footprint
  const SpeedLimits limits = AnalyseSpeedLimits(options);
  EXPECT_NEAR(limits.footprint_along_mm, 120.0, 1e-9);
  EXPECT_NEAR(limits.overlap_limit_mps, 1.8, 1e-9);
  EXPECT_NEAR(limits.instability_ratio, 2.0, 1e-12);
}

// At the overlap limit, consecutive footprints share exactly beta of their length along the
// travel: the shifted rectangle's centre is (1 - beta) Lambda away, and one more Lambda
// (beta = 0) puts it exactly on the other's edge, whatever the direction.
TEST(SpeedLimits, OverlapLimitIsWhereFootprintsStopSharingBeta) {
  std::mt19937 random(7);
  std::uniform_real_distribution<double> angle(-std::numbers::pi, std::numbers::pi), beta(0.0, 0.9);
  for (int i = 0; i < 100; ++i) {
    SpeedLimitOptions options;
    options.travel_direction_rad = angle(random);
    options.required_overlap = beta(random);
    const SpeedLimits limits = AnalyseSpeedLimits(options);
    const double step_mm = 1e3 * limits.overlap_limit_mps * limits.cycle_s;
    const double dx = step_mm * std::cos(options.travel_direction_rad);
    const double dy = step_mm * std::sin(options.travel_direction_rad);
    // Largest relative offset along the image axes: 1 when the footprints just touch.
    const double relative = std::max(std::abs(dx) / 160.0, std::abs(dy) / 120.0);
    EXPECT_NEAR(relative, 1.0 - options.required_overlap, 1e-9) << options.travel_direction_rad;
  }
}

// The distortion limit against a pinhole camera: at the limit speed the floor rises by
// g S between frames, and the corner of the image of the raised floor lies e pixels from
// where the calibrated height puts it.
TEST(SpeedLimits, DistortionLimitMatchesAPinholeCamera) {
  SpeedLimitOptions options;
  options.depth_gradient = 0.004;
  const SpeedLimits limits = AnalyseSpeedLimits(options);
  const double rise_mm = options.depth_gradient * 1e3 * limits.distortion_limit_mps * limits.cycle_s;
  camera::RealCameraOptions calibrated;
  calibrated.fx_px = calibrated.fy_px = options.camera_height_mm / options.mm_per_px;  // 0.25 mm/px
  camera::RealCameraOptions raised = calibrated;
  raised.height_mm = calibrated.height_mm - rise_mm;  // the floor came closer
  const camera::RealCamera before(calibrated), after(raised);
  // The floor point under the image corner (-319.5, -239.5 px from the centre is 400 px away
  // up to half a pixel).
  const Eigen::Vector2d corner_mm(320.0 * options.mm_per_px, 240.0 * options.mm_per_px);
  const auto p0 = before.FloorToPixel(corner_mm), p1 = after.FloorToPixel(corner_mm);
  ASSERT_TRUE(p0 && p1);
  EXPECT_NEAR((*p1 - *p0).norm(), options.distortion_tolerance_px, 0.01 * options.distortion_tolerance_px);
}

// The watch agrees with the analysis: a drive along the view's long side (160 mm at 0.25 mm
// per pixel) at 30 frames/s is over the limit (1.2 m/s for beta 0.5) only above it; it says
// so once per episode, and frames on the map are not judged.
TEST(OverlapSpeedWatch, JudgesEachStepAgainstTheLimitAlongItsDirection) {
  const camera::IdealCamera camera({640, 480, 0.25});
  SpeedLimitOptions setup;
  setup.frame_rate_hz = 30.0;
  const double limit_mps = AnalyseSpeedLimits(setup).overlap_limit_mps;
  ASSERT_NEAR(limit_mps, 2.4, 1e-9);  // 160 mm x 0.5 per 1/30 s
  OverlapSpeedWatch watch(camera, 0.5);
  const core::Duration period = core::FromSeconds(1.0 / 30.0);
  core::Timestamp time{};
  double x_mm = 0.0;
  int said = 0;
  auto drive = [&](double speed_mps, int frames, bool mapping) {
    int over = 0;
    for (int i = 0; i < frames; ++i) {
      time = time + period;
      x_mm += 1e3 * speed_mps / 30.0;
      const auto excess = watch.Frame(time, core::Pose2(x_mm, 0.0, 0.0), mapping);
      if (excess) {
        ++over;
        said += excess->first ? 1 : 0;
        EXPECT_NEAR(excess->speed_mps, speed_mps, 1e-6);  // the period rounded to ns
        EXPECT_NEAR(excess->limit_mps, limit_mps, 1e-6);
      }
    }
    return over;
  };
  EXPECT_EQ(drive(2.3, 30, true), 0);
  EXPECT_EQ(drive(2.5, 30, true), 30);
  EXPECT_EQ(said, 1);
  EXPECT_EQ(drive(3.0, 30, false), 0);  // on the map: not judged
  EXPECT_EQ(drive(2.5, 10, true), 10);
  EXPECT_EQ(said, 1);  // within kQuietS of the last excess
  EXPECT_EQ(watch.frames_over(), 40);
  EXPECT_NEAR(watch.max_speed_mps(), 2.5, 1e-6);  // the 3 m/s on the map not counted
  // Along the short side (120 mm), 2.0 m/s is over: 1.8 m/s is the limit there.
  OverlapSpeedWatch across(camera, 0.5);
  const auto first = across.Frame(core::Timestamp{}, core::Pose2(0.0, 0.0, 0.0), true);
  const auto second = across.Frame(core::Timestamp{} + period, core::Pose2(0.0, 2000.0 / 30.0, 0.0), true);
  EXPECT_FALSE(first);
  ASSERT_TRUE(second);
  EXPECT_NEAR(second->limit_mps, 1.8, 1e-6);
  EXPECT_TRUE(second->first);
  EXPECT_THROW(OverlapSpeedWatch(camera, 1.0), core::Error);
}

TEST(SpeedLimits, BadOptionsAreRejected) {
  SpeedLimitOptions options;
  options.required_overlap = 1.0;
  std::string why;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_EQ(why, "required_overlap must be in [0, 1)");
  EXPECT_THROW(AnalyseSpeedLimits(options), core::Error);
  options = SpeedLimitOptions{};
  options.frame_rate_hz = 0.0;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_EQ(why, "frame_rate_hz must be > 0");
}

}  // namespace
}  // namespace mosaicloc::localizer
