#include <tuple>

#include <gtest/gtest.h>

#include "../src/simd.hpp"
#include "mosaicloc/tracking/refine.hpp"
#include "tracking_test_support.hpp"

namespace mosaicloc::tracking {
namespace {

class RefineMethods : public ::testing::TestWithParam<std::tuple<RefineMethod, RefineWarp>> {};

TEST_P(RefineMethods, RecoversASubPixelShift) {
  REQUIRE_ASPHALT(texture);
  const Scene scene(*texture);
  const Pose2 truth(0.37 * kMmPerPx, -0.61 * kMmPerPx, 0.0);
  const cv::Mat frame = scene.Frame(truth, 1.0, 1.1, -8.0);
  RefineOptions options;
  options.method = std::get<0>(GetParam());
  options.warp = std::get<1>(GetParam());
  options.max_iterations = 50;
  const Affine frame_to_raster =
      ComposeAffine(scene.reference().WorldToRaster(), scene.camera().PixelToWorldAffine(Pose2::Identity()));
  const cv::Rect rect(250, 180, 96, 96);
  const RefinedMatch match = RefineTemplate(frame, rect, scene.reference(), frame_to_raster, options);
  ASSERT_TRUE(match.ok()) << ToString(match.failure) << " " << match.detail;
  const Eigen::Vector2d centre(rect.x + 47.5, rect.y + 47.5);
  const Eigen::Vector2d expected = scene.reference().WorldToRaster().leftCols<2>() *
                                       scene.camera().PixelToWorld(centre, truth) +
                                   scene.reference().WorldToRaster().col(2);
  const double tolerance = options.method == RefineMethod::kDirect ? 0.03 : 0.1;
  EXPECT_NEAR(match.centre_raster.x(), expected.x(), tolerance);
  EXPECT_NEAR(match.centre_raster.y(), expected.y(), tolerance);
  EXPECT_GT(match.zncc, 0.95);
}

INSTANTIATE_TEST_SUITE_P(
    AllMethods, RefineMethods,
    ::testing::Values(std::make_tuple(RefineMethod::kDirect, RefineWarp::kTranslation),
                      std::make_tuple(RefineMethod::kVispSsd, RefineWarp::kTranslation),
                      std::make_tuple(RefineMethod::kVispSsd, RefineWarp::kSrt),
                      std::make_tuple(RefineMethod::kVispSsd, RefineWarp::kHomography),
                      std::make_tuple(RefineMethod::kVispZncc, RefineWarp::kTranslation),
                      std::make_tuple(RefineMethod::kVispZncc, RefineWarp::kSrt),
                      std::make_tuple(RefineMethod::kVispZncc, RefineWarp::kHomography)));

// Starts a few pixels off, beyond the block the refinement filters first, so it has to fetch
// the larger block on the way; also turned, so the samples are not on the raster's grid.
TEST(Refine, DirectRecoversAShiftOfSeveralPixels) {
  REQUIRE_ASPHALT(texture);
  const Scene scene(*texture);
  for (const Pose2& truth : {Pose2(4.3 * kMmPerPx, -3.2 * kMmPerPx, 0.0), Pose2(-5.6 * kMmPerPx, 0.4 * kMmPerPx, 0.0),
                            Pose2(0.8 * kMmPerPx, 6.1 * kMmPerPx, 0.5 * kDeg)}) {
    const cv::Mat frame = scene.Frame(truth, 1.0);
    const Pose2 start(0.0, 0.0, truth.yaw_rad());
    const Affine frame_to_raster =
        ComposeAffine(scene.reference().WorldToRaster(), scene.camera().PixelToWorldAffine(start));
    const cv::Rect rect(250, 180, 96, 96);
    RefineOptions options;
    options.max_iterations = 50;
    const RefinedMatch match = RefineTemplate(frame, rect, scene.reference(), frame_to_raster, options);
    ASSERT_TRUE(match.ok()) << ToString(match.failure) << " " << match.detail;
    const Eigen::Vector2d centre(rect.x + 47.5, rect.y + 47.5);
    const Eigen::Vector2d expected = scene.reference().WorldToRaster().leftCols<2>() *
                                         scene.camera().PixelToWorld(centre, truth) +
                                     scene.reference().WorldToRaster().col(2);
    EXPECT_NEAR(match.centre_raster.x(), expected.x(), 0.03);
    EXPECT_NEAR(match.centre_raster.y(), expected.y(), 0.03);
  }
}

// A quarter of the template shows the floor 2.5 px further on (a joint's bottom seen from
// elsewhere in the view): least squares is pulled towards it; the reweighted fit follows the
// other three quarters.
TEST(Refine, RobustReweightingIgnoresAPartThatMovedElsewhere) {
  REQUIRE_ASPHALT(texture);
  const Scene scene(*texture);
  const Pose2 truth(0.3 * kMmPerPx, -0.2 * kMmPerPx, 0.0);
  cv::Mat frame = scene.Frame(truth, 1.0);
  const cv::Mat moved = scene.Frame(Pose2(truth.x_mm() + 2.5 * kMmPerPx, truth.y_mm(), 0.0), 1.0);
  const cv::Rect rect(250, 180, 96, 96);
  const cv::Rect quarter(rect.x + 48, rect.y + 48, 48, 48);
  moved(quarter).copyTo(frame(quarter));
  const Affine frame_to_raster =
      ComposeAffine(scene.reference().WorldToRaster(), scene.camera().PixelToWorldAffine(Pose2::Identity()));
  const Eigen::Vector2d centre(rect.x + 47.5, rect.y + 47.5);
  const Eigen::Vector2d expected = scene.reference().WorldToRaster().leftCols<2>() *
                                       scene.camera().PixelToWorld(centre, truth) +
                                   scene.reference().WorldToRaster().col(2);
  RefineOptions options;
  options.max_iterations = 50;
  const RefinedMatch plain = RefineTemplate(frame, rect, scene.reference(), frame_to_raster, options);
  options.robust = true;
  const RefinedMatch robust = RefineTemplate(frame, rect, scene.reference(), frame_to_raster, options);
  ASSERT_TRUE(plain.ok()) << ToString(plain.failure) << " " << plain.detail;
  ASSERT_TRUE(robust.ok()) << ToString(robust.failure) << " " << robust.detail;
  const double plain_error = (plain.centre_raster - expected).norm();
  const double robust_error = (robust.centre_raster - expected).norm();
  EXPECT_GT(plain_error, 0.2);
  EXPECT_LT(robust_error, 0.05);
  // On an unchanged template the two agree.
  const cv::Mat clean = scene.Frame(truth, 1.0);
  options.robust = false;
  const RefinedMatch clean_plain = RefineTemplate(clean, rect, scene.reference(), frame_to_raster, options);
  options.robust = true;
  const RefinedMatch clean_robust = RefineTemplate(clean, rect, scene.reference(), frame_to_raster, options);
  ASSERT_TRUE(clean_plain.ok() && clean_robust.ok());
  EXPECT_LT((clean_plain.centre_raster - clean_robust.centre_raster).norm(), 0.02);
  EXPECT_LT((clean_robust.centre_raster - expected).norm(), 0.03);
}

// The AVX2 build of the refinement's sampling loop (when the processor has it) and the
// baseline build give the same match bit for bit, inside the reference and at its edge.
TEST(Refine, DirectVectorBuildsAgreeExactly) {
  REQUIRE_ASPHALT(texture);
  const Scene scene(*texture, {600, 500});
  const Pose2 truth(0.37 * kMmPerPx, -0.61 * kMmPerPx, 0.3 * kDeg);
  const cv::Mat frame = scene.Frame(truth, 1.0, 1.1, -8.0);
  const Affine frame_to_raster =
      ComposeAffine(scene.reference().WorldToRaster(), scene.camera().PixelToWorldAffine(Pose2::Identity()));
  for (const cv::Rect rect : {cv::Rect(250, 180, 96, 96), cv::Rect(40, 30, 64, 80), cv::Rect(16, 200, 96, 96)}) {
    const RefinedMatch fast = RefineTemplate(frame, rect, scene.reference(), frame_to_raster, RefineOptions{});
    detail::SetAvx2Allowed(false);
    const RefinedMatch plain = RefineTemplate(frame, rect, scene.reference(), frame_to_raster, RefineOptions{});
    detail::SetAvx2Allowed(true);
    ASSERT_EQ(fast.failure, plain.failure);
    EXPECT_EQ(fast.iterations, plain.iterations);
    EXPECT_EQ(fast.centre_raster, plain.centre_raster);
    EXPECT_EQ(fast.covariance_px2, plain.covariance_px2);
    EXPECT_EQ(fast.zncc, plain.zncc);
  }
}

TEST(Refine, TemplateLeavingTheReferenceIsAFailureNotACrash) {
  REQUIRE_ASPHALT(texture);
  const Scene scene(*texture, {400, 400});
  // The frame centre sits near the reference's corner: most templates fall off it.
  const Pose2 prior(45.0, -45.0, 0.0);
  const cv::Mat frame = scene.Frame(Pose2(45.0, -45.0, 0.0));
  const Affine frame_to_raster =
      ComposeAffine(scene.reference().WorldToRaster(), scene.camera().PixelToWorldAffine(prior));
  for (const RefineMethod method : {RefineMethod::kDirect, RefineMethod::kVispSsd, RefineMethod::kVispZncc}) {
    RefineOptions options;
    options.method = method;
    const RefinedMatch match = RefineTemplate(frame, cv::Rect(400, 60, 96, 96), scene.reference(), frame_to_raster,
                                              options);
    EXPECT_FALSE(match.ok());
  }
}

}  // namespace
}  // namespace mosaicloc::tracking
