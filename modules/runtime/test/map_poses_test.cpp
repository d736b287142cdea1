#include "mosaicloc/runtime/map_poses.hpp"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

namespace mosaicloc::runtime {
namespace {

constexpr int kWidth = 80, kHeight = 60;

// A camera whose corners get 15 % less light.
float Vignetting(int x, int y) {
  const double u = (x - 0.5 * (kWidth - 1)) / (0.5 * kWidth), v = (y - 0.5 * (kHeight - 1)) / (0.5 * kHeight);
  return static_cast<float>(1.0 - 0.075 * (u * u + v * v));
}

// Its view of a random floor at `x_mm` along a straight line, 1 mm a pixel.
cv::Mat View(const cv::Mat& floor, int x_mm) {
  cv::Mat frame(kHeight, kWidth, CV_8UC1);
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      frame.at<std::uint8_t>(y, x) =
          cv::saturate_cast<std::uint8_t>(floor.at<std::uint8_t>(y, x + x_mm) * Vignetting(x, y));
    }
  }
  return frame;
}

class MappingFlatFieldEstimate : public ::testing::Test {
 protected:
  void SetUp() override {
    floor_.create(kHeight, 40'000, CV_8UC1);
    cv::RNG rng(7);
    rng.fill(floor_, cv::RNG::UNIFORM, 60, 200);
  }
  // Frames every `step_mm` along the line; the wheels say where.
  void Drive(int frames, int step_mm) {
    for (int i = 0; i < frames; ++i) {
      wheels_.emplace_back(static_cast<double>(i * step_mm), 0.0, 0.0);
      frames_.push_back(View(floor_, i * step_mm));
    }
  }
  MappingFlatField Estimate(const std::vector<std::size_t>& starts, double spacing_mm, int max_frames = 400) {
    loaded_ = 0;
    return EstimateMappingFlatField(
        [this](std::size_t i) {
          ++loaded_;
          return frames_.at(i);
        },
        wheels_, starts, spacing_mm, max_frames);
  }
  cv::Mat floor_;
  std::vector<cv::Mat> frames_;
  std::vector<core::Pose2> wheels_;
  int loaded_ = 0;
};

TEST_F(MappingFlatFieldEstimate, RecoversTheCamerasVignettingFromFramesAViewApart) {
  Drive(600, 20);  // 12 m
  const MappingFlatField field = Estimate({0}, kWidth, 100);
  ASSERT_FALSE(field.gain.empty());
  // The spacing grew to keep to 100 frames over the drive (121 mm, so every seventh frame of
  // these 20 mm apart): only those were read.
  EXPECT_EQ(field.flat_frames, 86);
  EXPECT_EQ(loaded_, 86);
  // Both relative to their means.
  double truth_mean = 0.0;
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) truth_mean += Vignetting(x, y);
  }
  truth_mean /= kWidth * kHeight;
  const double mean = cv::mean(field.gain)[0];
  // The median of 86 views of a floor whose grey spreads over 140 DN is good to a few per cent
  // a pixel; the smooth fit over the image to about one.
  double sum_sq = 0.0;
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      const double error = field.gain.at<float>(y, x) / mean - Vignetting(x, y) / truth_mean;
      sum_sq += error * error;
    }
  }
  EXPECT_LT(std::sqrt(sum_sq / (kWidth * kHeight)), 0.015);
  EXPECT_NEAR(field.max_gain / field.min_gain, 1.0 / 0.85, 0.03);
}

TEST_F(MappingFlatFieldEstimate, AVehicleThatHardlyMovedGivesNone) {
  // 2 m in 2 mm steps: 20 frames 100 mm apart, fewer than the 24 needed.
  Drive(1000, 2);
  EXPECT_TRUE(Estimate({0}, 100.0).gain.empty());
  EXPECT_EQ(loaded_, 0) << "no frame is read for an estimate that cannot be made";
}

TEST_F(MappingFlatFieldEstimate, EveryDriveIsSampledFromItsStart) {
  // Two drives of 30 frames 100 mm apart over different floor; the second's wheels start at
  // the very pose the first's ended at (each drive's wheels have their own origin).
  Drive(30, 100);
  for (int i = 0; i < 30; ++i) {
    wheels_.emplace_back(static_cast<double>(2900 + i * 100), 0.0, 0.0);
    frames_.push_back(View(floor_, 20'000 + i * 100));
  }
  const MappingFlatField field = Estimate({0, 30}, 100.0);
  EXPECT_EQ(field.flat_frames, 60) << "the second drive's first frame is taken, though its wheels have not moved";
}

}  // namespace
}  // namespace mosaicloc::runtime
