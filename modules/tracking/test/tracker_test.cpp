#include <algorithm>
#include <cmath>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/tracking/tracker.hpp"
#include "tracking_test_support.hpp"

namespace mosaicloc::tracking {
namespace {

TEST(Tracker, RecoversSyntheticWarpsOfARealTexture) {
  REQUIRE_ASPHALT(texture);
  const Scene scene(*texture);
  const Tracker tracker(scene.camera(), TrackerOptions{});
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> shift(-8.0, 8.0), turn(-3.0, 3.0);
  double sum_sq_px = 0.0, sum_sq_deg = 0.0;
  const int trials = 12;
  for (int t = 0; t < trials; ++t) {
    const Pose2 truth(shift(rng) * kMmPerPx, shift(rng) * kMmPerPx, turn(rng) * kDeg);
    const cv::Mat frame = scene.Frame(truth, 2.0, 0.9, 12.0, static_cast<std::uint64_t>(t));
    const TrackResult r = tracker.Track(frame, Pose2::Identity(), PriorCovariance(8.0 / 3.0, 1.0), scene.reference());
    ASSERT_TRUE(r.ok()) << "trial " << t << ": " << Describe(r);
    const double error_px = Distance(r.world_from_camera, truth) / kMmPerPx;
    const double error_deg = std::abs(YawDifference(r.world_from_camera, truth)) / kDeg;
    EXPECT_LT(error_px, 0.06) << "trial " << t;
    sum_sq_px += error_px * error_px;
    sum_sq_deg += error_deg * error_deg;
  }
  const double rms_px = std::sqrt(sum_sq_px / trials);
  const double rms_deg = std::sqrt(sum_sq_deg / trials);
  RecordProperty("rms_px", std::to_string(rms_px));
  EXPECT_LE(rms_px, 0.02);
  EXPECT_LE(rms_deg, 0.01);
}

// A camera higher or lower than calibrated (a floor lower or higher than mapped): with the
// scale estimated, the pose holds to what it does at the calibrated height and the scale is
// measured; seeded with the scale found, the next frame starts where it should.
TEST(Tracker, EstimatesTheImageScaleOfAHigherCamera) {
  REQUIRE_ASPHALT(texture);
  const Scene scene(*texture);
  const Tracker tracker(scene.camera(), TrackerOptions{});  // estimates the scale
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> shift(-6.0, 6.0), turn(-2.0, 2.0);
  for (const double k : {0.98, 0.995, 1.0, 1.005, 1.02}) {
    for (int t = 0; t < 3; ++t) {
      const Pose2 truth(shift(rng) * kMmPerPx, shift(rng) * kMmPerPx, turn(rng) * kDeg);
      const cv::Mat frame = scene.Frame(truth, 2.0, 1.0, 0.0, static_cast<std::uint64_t>(t), k);
      const TrackResult r =
          tracker.Track(frame, Pose2::Identity(), PriorCovariance(8.0 / 3.0, 1.0), scene.reference());
      ASSERT_TRUE(r.ok()) << "scale " << k << " trial " << t << ": " << Describe(r);
      ASSERT_TRUE(r.scale_estimated);
      EXPECT_NEAR(r.scale, k, 2e-4) << "trial " << t;
      EXPECT_LT(Distance(r.world_from_camera, truth) / kMmPerPx, 0.06) << "scale " << k << " trial " << t;
      EXPECT_LT(std::abs(YawDifference(r.world_from_camera, truth)) / kDeg, 0.02) << "scale " << k;
      const TrackResult seeded =
          tracker.Track(frame, truth, PriorCovariance(0.5, 0.1), scene.reference(), r.scale);
      ASSERT_TRUE(seeded.ok()) << Describe(seeded);
      EXPECT_NEAR(seeded.scale, k, 2e-4);
    }
  }
  // Without the estimate, a 2 % higher camera pulls the fit off or loses it.
  TrackerOptions rigid_options;
  rigid_options.solver.estimate_scale = false;
  const Tracker rigid(scene.camera(), rigid_options);
  const Pose2 truth(0.5, -0.25, 0.5 * kDeg);
  const TrackResult r = rigid.Track(scene.Frame(truth, 2.0, 1.0, 0.0, 1, 1.02), Pose2::Identity(),
                                    PriorCovariance(8.0 / 3.0, 1.0), scene.reference());
  EXPECT_FALSE(r.scale_estimated);
  EXPECT_TRUE(!r.ok() || r.rms_residual_mm > 0.05) << Describe(r);
}

TEST(Tracker, ReportsACovarianceConsistentWithItsError) {
  REQUIRE_ASPHALT(texture);
  const Scene scene(*texture);
  const Tracker tracker(scene.camera(), TrackerOptions{});
  const Pose2 truth(1.0, -0.5, 1.0 * kDeg);
  const TrackResult r =
      tracker.Track(scene.Frame(truth, 2.0), Pose2::Identity(), PriorCovariance(3.0, 1.0), scene.reference());
  ASSERT_TRUE(r.ok()) << r.reason;
  const double sigma_mm = std::sqrt(r.covariance(0, 0));
  EXPECT_GT(sigma_mm, 1e-4);
  EXPECT_LT(sigma_mm, 0.01);
  EXPECT_LT(std::abs(r.world_from_camera.x_mm() - truth.x_mm()), 5.0 * sigma_mm + 0.002);
}

TEST(Tracker, BlankFrameHasNoTexture) {
  REQUIRE_ASPHALT(texture);
  const Scene scene(*texture);
  const Tracker tracker(scene.camera(), TrackerOptions{});
  const cv::Mat blank(480, 640, CV_8UC1, cv::Scalar(120));
  const TrackResult r = tracker.Track(blank, Pose2::Identity(), PriorCovariance(2.0, 0.2), scene.reference());
  EXPECT_EQ(r.failure, TrackFailure::kNoTexture);
}

// A frame textured only in one spot: whatever the tracker returns, its yaw is never more
// certain than the frame allows (the spot's templates once all coincided, giving a yaw of
// variance zero from a single point).
TEST(Tracker, FrameTexturedInOneSpotClaimsNoYawItCannotSee) {
  REQUIRE_ASPHALT(texture);
  const Scene scene(*texture);
  const Tracker tracker(scene.camera(), TrackerOptions{});
  const Pose2 truth(0.6, -0.4, 0.3 * kDeg);
  const cv::Mat full = scene.Frame(truth, 1.0);
  for (const int size : {96, 112, 160}) {
    cv::Mat frame(full.size(), CV_8UC1, cv::Scalar(cv::mean(full)[0]));
    const cv::Rect spot(320 - size / 2, 240 - size / 2, size, size);
    full(spot).copyTo(frame(spot));
    const TrackResult r = tracker.Track(frame, Pose2::Identity(), PriorCovariance(3.0, 0.5), scene.reference());
    if (!r.ok()) {
      EXPECT_TRUE(r.failure == TrackFailure::kTooFewInliers || r.failure == TrackFailure::kNoTexture)
          << size << ": " << Describe(r);
      continue;
    }
    const double yaw_error = std::abs(YawDifference(r.world_from_camera, truth));
    EXPECT_TRUE(std::isfinite(r.covariance(2, 2)) && r.covariance(2, 2) > 0.0) << size << ": " << r.covariance;
    EXPECT_LT(yaw_error, 5.0 * std::sqrt(r.covariance(2, 2)) + 1e-6) << size << ": " << Describe(r);
  }
}

TEST(Tracker, FrameOffTheMapSaysSo) {
  REQUIRE_ASPHALT(texture);
  const Scene scene(*texture);
  const Tracker tracker(scene.camera(), TrackerOptions{});
  const cv::Mat frame = scene.Frame(Pose2::Identity());
  const TrackResult r = tracker.Track(frame, Pose2(2000.0, 0.0, 0.0), PriorCovariance(2.0, 0.2), scene.reference());
  EXPECT_EQ(r.failure, TrackFailure::kOffMap) << r.reason;
}

TEST(Tracker, RepetitiveFloorIsAmbiguousNotMatchedWrongly) {
  // A floor that repeats every 24 px: with a search range beyond the period every template
  // matches in several places, and the tracker must say so rather than pick one.
  REQUIRE_ASPHALT(texture);
  cv::Mat cell = (*texture)(cv::Rect(500, 500, 48, 48)).clone();
  cv::Mat periodic;
  cv::repeat(cell, 44, 44, periodic);
  const Scene scene(periodic);
  const Tracker tracker(scene.camera(), TrackerOptions{});
  const Pose2 truth(1.0, 1.0, 0.0);
  const TrackResult r =
      tracker.Track(scene.Frame(truth, 1.0), Pose2::Identity(), PriorCovariance(12.0, 0.1), scene.reference());
  EXPECT_EQ(r.failure, TrackFailure::kAmbiguous) << r.reason;
  for (const TemplateReport& t : r.templates) {
    EXPECT_FALSE(t.rejected.empty()) << "template at " << t.spot.rect.x << "," << t.spot.rect.y << " used: peak "
                                     << t.coarse.peak << " second " << t.coarse.second << " range "
                                     << t.search_range_px;
  }
}

TEST(Tracker, AnyRefinementMethodGivesThePose) {
  REQUIRE_ASPHALT(texture);
  const Scene scene(*texture);
  const Pose2 truth(-1.2, 0.8, -1.5 * kDeg);
  const cv::Mat frame = scene.Frame(truth, 1.0);
  for (const RefineMethod method : {RefineMethod::kVispSsd, RefineMethod::kVispZncc}) {
    for (const RefineWarp warp : {RefineWarp::kTranslation, RefineWarp::kSrt, RefineWarp::kHomography}) {
      TrackerOptions options;
      options.refine.method = method;
      options.refine.warp = warp;
      const Tracker tracker(scene.camera(), options);
      const TrackResult r = tracker.Track(frame, Pose2::Identity(), PriorCovariance(3.0, 1.0), scene.reference());
      ASSERT_TRUE(r.ok()) << r.reason;
      EXPECT_LT(Distance(r.world_from_camera, truth) / kMmPerPx, 0.15);
    }
  }
}

TEST(VisualOdometry, RegistersConsecutiveFrames) {
  REQUIRE_ASPHALT(texture);
  const Scene scene(*texture);
  // A quarter-frame move takes some templates out of the previous frame: use nine.
  TrackerOptions options;
  options.templates.count = 9;
  const Tracker tracker(scene.camera(), options);
  const Pose2 first(-10.0, 5.0, 0.02);
  const Pose2 second = first * Pose2(30.0, 2.0, 0.01);  // 120 px forward, a quarter of the frame
  const TrackResult r =
      RegisterFrames(tracker, scene.Frame(first, 2.0, 1.0, 0.0, 1), scene.Frame(second, 2.0, 1.0, 0.0, 2),
                     Pose2(29.0, 2.5, 0.0), PriorCovariance(4.0, 0.5));
  ASSERT_TRUE(r.ok()) << r.reason;
  const Pose2 truth = Between(first, second);
  EXPECT_LT(Distance(r.world_from_camera, truth), 0.01);
  EXPECT_LT(std::abs(YawDifference(r.world_from_camera, truth)), 2e-5);
}

// Frames prepared once (their half images and templates) register exactly as the frames do.
TEST(VisualOdometry, PreparedFramesRegisterAsTheFramesDo) {
  REQUIRE_ASPHALT(texture);
  const Scene scene(*texture);
  TrackerOptions options;
  options.templates.count = 9;
  const Tracker tracker(scene.camera(), options);
  const Pose2 first(-10.0, 5.0, 0.02);
  const Pose2 second = first * Pose2(30.0, 2.0, 0.01);
  const cv::Mat a = scene.Frame(first, 2.0, 1.0, 0.0, 1), b = scene.Frame(second, 2.0, 1.0, 0.0, 2);
  const TrackResult plain = RegisterFrames(tracker, a, b, Pose2(29.0, 2.5, 0.0), PriorCovariance(4.0, 0.5));
  const TrackResult prepared =
      RegisterFrames(tracker, tracker.Prepare(a), tracker.Prepare(b), Pose2(29.0, 2.5, 0.0), PriorCovariance(4.0, 0.5));
  ASSERT_TRUE(plain.ok() && prepared.ok()) << plain.reason << prepared.reason;
  EXPECT_EQ(prepared.world_from_camera.x_mm(), plain.world_from_camera.x_mm());
  EXPECT_EQ(prepared.world_from_camera.y_mm(), plain.world_from_camera.y_mm());
  EXPECT_EQ(prepared.world_from_camera.yaw_rad(), plain.world_from_camera.yaw_rad());
  EXPECT_EQ(prepared.covariance, plain.covariance);
  EXPECT_EQ(prepared.templates.size(), plain.templates.size());
  // A frame the tracker cannot take is prepared as nothing, and refused as before.
  const PreparedFrame wrong = tracker.Prepare(cv::Mat(10, 10, CV_8UC1, cv::Scalar(0)));
  EXPECT_TRUE(wrong.spots.empty());
  const TrackResult refused = RegisterFrames(tracker, tracker.Prepare(a), wrong, Pose2(), PriorCovariance(4.0, 0.5));
  EXPECT_EQ(refused.failure, TrackFailure::kNoTexture);
}

}  // namespace
}  // namespace mosaicloc::tracking
