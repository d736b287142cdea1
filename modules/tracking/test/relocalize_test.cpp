#include <optional>
#include <string>

#include <gtest/gtest.h>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/tracking/relocalize.hpp"
#include "tracking_test_support.hpp"

namespace mosaicloc::tracking {
namespace {

TrackResult Verified(double x_mm, double zncc) {
  TrackResult r;
  r.world_from_camera = Pose2(x_mm, 0.0, 0.0);
  r.mean_zncc = zncc;
  return r;
}

TEST(ChooseRelocalization, TakesTheNearestOfEqualPlacesOnlyWhenThePredictionDecides) {
  const Pose2 prior(0.0, 0.0, 0.0);
  EXPECT_EQ(ChooseRelocalization({Verified(300.0, 0.9)}, prior, 0.02, 2.0).world_from_camera.x_mm(), 300.0)
      << "one place: taken however far";
  const auto two = [&](double near_mm, double far_mm) {
    return ChooseRelocalization({Verified(far_mm, 0.95), Verified(near_mm, 0.95)}, prior, 0.02, 2.0);
  };
  EXPECT_EQ(two(40.0, -216.0).world_from_camera.x_mm(), 40.0);
  const TrackResult halfway = two(120.0, -136.0);
  EXPECT_EQ(halfway.failure, TrackFailure::kAmbiguous);
  EXPECT_NE(halfway.reason.find("2 places"), std::string::npos) << halfway.reason;
  EXPECT_NE(halfway.reason.find("256 mm apart"), std::string::npos) << halfway.reason;
  // A clearly better match is no tie, even if farther.
  EXPECT_EQ(ChooseRelocalization({Verified(10.0, 0.85), Verified(200.0, 0.97)}, prior, 0.02, 2.0)
                .world_from_camera.x_mm(),
            200.0);
}

// A frame away from the prediction is found when the radius reaches it; a gate that the
// prediction's covariance keeps tight refuses it, and says how far off it was.
TEST(Relocalizer, FindsTheFrameWithinTheRadiusAndKeepsToTheGate) {
  REQUIRE_ASPHALT(texture);
  const Scene scene(*texture);
  const Tracker tracker(scene.camera(), TrackerOptions{});
  RelocalizeOptions options;
  options.level = 2;
  const Relocalizer relocalizer(tracker, scene.reference(), options);
  const Pose2 truth(30.0, -20.0, 0.004);
  const cv::Mat frame = scene.Frame(truth, 1.0);
  const Pose2 prior = Pose2::Identity();
  const Eigen::Matrix3d covariance = PriorCovariance(4.0, 0.5);
  const TrackResult found = relocalizer.Search(frame, prior, covariance, 60.0, std::nullopt);
  ASSERT_TRUE(found.ok()) << Describe(found);
  EXPECT_LT(Distance(found.world_from_camera, truth), 0.01);
  const TrackResult gated = relocalizer.Search(frame, prior, covariance, 60.0, RelocalizeGate{11.8, 4.0});
  EXPECT_EQ(gated.failure, TrackFailure::kNoMatch);
  EXPECT_NE(gated.reason.find("none within the prediction's uncertainty (the nearest 36 mm off"), std::string::npos)
      << gated.reason;
  EXPECT_NE(gated.reason.find(" against 11.8)"), std::string::npos) << "the gate it failed, named: " << gated.reason;
}

TEST(Relocalizer, RejectsBadOptions) {
  const camera::IdealCamera camera{camera::IdealCameraOptions{}};
  const Tracker tracker(camera, TrackerOptions{});
  const ImageReference reference(cv::Mat(64, 64, CV_8UC1, cv::Scalar(9)), Pose2::Identity(), kMmPerPx);
  RelocalizeOptions options;
  options.nearer_factor = 0.5;
  std::string why;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_EQ(why, "relocalization nearer_factor must be >= 1");
  EXPECT_THROW(Relocalizer(tracker, reference, options), core::Error);
}

}  // namespace
}  // namespace mosaicloc::tracking
