#include <cstdint>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "../src/low_pass.hpp"
#include "../src/simd.hpp"
#include "mosaicloc/core/error.hpp"

namespace mosaicloc::tracking {
namespace {

cv::Mat RandomImage(int cols, int rows, std::uint32_t seed) {
  cv::Mat image(rows, cols, CV_8UC1);
  std::mt19937 random(seed);
  std::uniform_int_distribution<int> grey(0, 255);
  for (int y = 0; y < rows; ++y) {
    for (int x = 0; x < cols; ++x) image.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(grey(random));
  }
  return image;
}

cv::Mat OpenCvFloat(const cv::Mat& image, double sigma) {
  cv::Mat f, blurred;
  image.convertTo(f, CV_32F);
  const int k = 2 * detail::LowPassRadius(sigma) + 1;
  cv::GaussianBlur(f, blurred, cv::Size(k, k), sigma, sigma, cv::BORDER_REPLICATE);
  return blurred;
}

TEST(LowPass, RadiusIsThreeSigmaRoundedUp) {
  EXPECT_EQ(detail::LowPassRadius(0.0), 0);
  EXPECT_EQ(detail::LowPassRadius(1.0), 3);
  EXPECT_EQ(detail::LowPassRadius(0.7), 3);
  EXPECT_EQ(detail::LowPassRadius(1.5), 5);
  EXPECT_EQ(detail::LowPassRadius(5.0), 15);
}

// Random images (the hardest case for a low-pass: all detail at the pixel scale), sizes from
// smaller than the kernel to the tracker's largest windows, sigmas across the options' range.
TEST(LowPass, FloatResultEqualsOpenCvGaussianBlurWithReplicatedBorders) {
  std::uint32_t seed = 1;
  for (const double sigma : {0.5, 1.0, 1.7, 3.0, 5.0}) {
    for (const cv::Size size : {cv::Size(1, 1), cv::Size(3, 5), cv::Size(9, 6), cv::Size(48, 48), cv::Size(61, 77),
                                cv::Size(130, 124)}) {
      const cv::Mat image = RandomImage(size.width, size.height, seed++);
      cv::Mat ours;
      detail::GaussianLowPass(image, ours, sigma, CV_32F);
      ASSERT_EQ(ours.type(), CV_32FC1);
      ASSERT_EQ(ours.size(), image.size());
      EXPECT_LE(cv::norm(ours, OpenCvFloat(image, sigma), cv::NORM_INF), 2e-3)
          << "sigma " << sigma << ", " << size.width << "x" << size.height;
    }
  }
}

TEST(LowPass, EightBitResultIsWithinOneGreyLevelOfOpenCv) {
  std::uint32_t seed = 100;
  for (const double sigma : {0.8, 1.0, 2.0}) {
    for (const cv::Size size : {cv::Size(7, 7), cv::Size(52, 52), cv::Size(96, 60), cv::Size(140, 140)}) {
      const cv::Mat image = RandomImage(size.width, size.height, seed++);
      cv::Mat ours, theirs;
      detail::GaussianLowPass(image, ours, sigma, CV_8U);
      cv::GaussianBlur(image, theirs, cv::Size(), sigma, sigma, cv::BORDER_REPLICATE);
      ASSERT_EQ(ours.type(), CV_8UC1);
      EXPECT_LE(cv::norm(ours, theirs, cv::NORM_INF), 1.0) << "sigma " << sigma;
      // And the rounding is of the exact float result, not a truncation.
      cv::Mat exact = OpenCvFloat(image, sigma), rounded;
      exact.convertTo(rounded, CV_8U);
      EXPECT_LE(cv::norm(ours, rounded, cv::NORM_INF), 1.0);
      EXPECT_LT(cv::countNonZero(ours != rounded), static_cast<int>(image.total() / 100 + 1));
    }
  }
}

TEST(LowPass, ConstantStaysConstantAndAViewIsFilteredAsItsPixels) {
  const cv::Mat flat(40, 30, CV_8UC1, cv::Scalar(200));
  cv::Mat out;
  detail::GaussianLowPass(flat, out, 1.0, CV_8U);
  EXPECT_EQ(cv::countNonZero(out != 200), 0);
  // A region of a larger image: its own borders are replicated, its neighbours unseen.
  const cv::Mat big = RandomImage(100, 100, 7);
  const cv::Mat view = big(cv::Rect(20, 30, 50, 40));
  cv::Mat from_view, from_copy;
  detail::GaussianLowPass(view, from_view, 1.0, CV_32F);
  detail::GaussianLowPass(view.clone(), from_copy, 1.0, CV_32F);
  EXPECT_EQ(cv::norm(from_view, from_copy, cv::NORM_INF), 0.0);
}

// The rectangle variant is the whole-image filter evaluated on part of it: the same pixels,
// bit for bit, with the image's own edges replicated and its inside read across the
// rectangle's edges.
TEST(LowPass, RectangleIsThePartOfTheWholeFilteredImage) {
  const cv::Mat image = RandomImage(90, 70, 21);
  for (const double sigma : {0.6, 1.0, 2.5}) {
    for (const int depth : {CV_32F, CV_8U}) {
      cv::Mat whole;
      detail::GaussianLowPass(image, whole, sigma, depth);
      for (const cv::Rect rect : {cv::Rect(0, 0, 90, 70), cv::Rect(10, 12, 40, 30), cv::Rect(0, 5, 7, 60),
                                  cv::Rect(83, 63, 7, 7), cv::Rect(45, 0, 1, 1), cv::Rect(2, 66, 88, 4)}) {
        cv::Mat part;
        detail::GaussianLowPassRect(image, rect, part, sigma, depth);
        ASSERT_EQ(part.size(), rect.size());
        EXPECT_EQ(cv::norm(part, whole(rect), cv::NORM_INF), 0.0)
            << "sigma " << sigma << " rect " << rect.x << "," << rect.y << " " << rect.width << "x" << rect.height;
      }
    }
  }
  cv::Mat out;
  EXPECT_THROW(detail::GaussianLowPassRect(image, cv::Rect(80, 0, 20, 10), out, 1.0, CV_32F), core::Error);
  EXPECT_THROW(detail::GaussianLowPassRect(image, cv::Rect(0, 0, 0, 10), out, 1.0, CV_32F), core::Error);
}

// The AVX2 build of the filter (when the processor has it) and the baseline build agree bit
// for bit: the same operations, more lanes at a time.
TEST(LowPass, VectorBuildsAgreeExactly) {
  for (const double sigma : {0.5, 1.0, 3.0}) {
    // Widths on both sides of multiples of the filter's block of 8 outputs.
    for (const cv::Size size : {cv::Size(5, 9), cv::Size(8, 11), cv::Size(15, 7), cv::Size(17, 20), cv::Size(48, 48),
                                cv::Size(63, 31), cv::Size(123, 117)}) {
      const cv::Mat image = RandomImage(size.width, size.height, 300 + size.width);
      for (const int depth : {CV_32F, CV_8U}) {
        cv::Mat fast, plain;
        detail::GaussianLowPass(image, fast, sigma, depth);
        detail::SetAvx2Allowed(false);
        detail::GaussianLowPass(image, plain, sigma, depth);
        detail::SetAvx2Allowed(true);
        EXPECT_EQ(cv::norm(fast, plain, cv::NORM_INF), 0.0) << "sigma " << sigma;
      }
    }
  }
}

TEST(LowPass, SigmaZeroConvertsAndBadInputThrows) {
  const cv::Mat image = RandomImage(10, 10, 3);
  cv::Mat out;
  detail::GaussianLowPass(image, out, 0.0, CV_32F);
  cv::Mat expected;
  image.convertTo(expected, CV_32F);
  EXPECT_EQ(cv::norm(out, expected, cv::NORM_INF), 0.0);
  EXPECT_THROW(detail::GaussianLowPass(cv::Mat(), out, 1.0, CV_8U), core::Error);
  EXPECT_THROW(detail::GaussianLowPass(cv::Mat(5, 5, CV_32F), out, 1.0, CV_8U), core::Error);
  EXPECT_THROW(detail::GaussianLowPass(image, out, 1.0, CV_16S), core::Error);
  EXPECT_THROW(detail::GaussianLowPass(image, out, 6.0, CV_8U), core::Error);
}

}  // namespace
}  // namespace mosaicloc::tracking
