#include "../src/binary_erode.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::tracking {
namespace {

// A mask like a map tile's: mapped lanes with holes, edges and specks, up to the border.
cv::Mat LaneMask(int rows, int cols, int seed) {
  cv::Mat mask(rows, cols, CV_8UC1, cv::Scalar(0));
  cv::RNG rng(static_cast<std::uint64_t>(seed));
  cv::rectangle(mask, cv::Rect(0, rows / 4, cols, rows / 2), cv::Scalar(255), cv::FILLED);
  cv::circle(mask, cv::Point(cols / 3, rows / 5), rows / 6, cv::Scalar(255), cv::FILLED);
  for (int i = 0; i < 40; ++i) {
    cv::circle(mask, cv::Point(rng.uniform(0, cols), rng.uniform(0, rows)), rng.uniform(1, 9),
               cv::Scalar(rng.uniform(0, 2) * 255), cv::FILLED);
  }
  return mask;
}

// The same pixels as OpenCV's erosion, for the shapes getStructuringElement makes, on masks
// that touch the border (OpenCV counts outside as set) and on an all-set mask.
TEST(ErodeBinary, IsOpenCvsErosionForCentredElements) {
  for (const int shape : {cv::MORPH_ELLIPSE, cv::MORPH_RECT, cv::MORPH_CROSS}) {
    for (const int size : {1, 3, 9, 45}) {
      const cv::Mat element = cv::getStructuringElement(shape, cv::Size(size, size));
      for (int seed = 1; seed <= 3; ++seed) {
        const cv::Mat mask = LaneMask(150 + seed * 7, 170 + seed * 11, seed);
        cv::Mat expected, got;
        cv::erode(mask, expected, element);
        detail::ErodeBinary(mask, element, &got);
        EXPECT_EQ(cv::countNonZero(expected != got), 0) << "shape " << shape << " size " << size << " seed " << seed;
      }
      const cv::Mat full(60, 70, CV_8UC1, cv::Scalar(255));
      cv::Mat got;
      detail::ErodeBinary(full, element, &got);
      EXPECT_EQ(cv::countNonZero(got), 60 * 70);
    }
  }
  // A non-square ellipse too.
  const cv::Mat wide = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(21, 9));
  const cv::Mat mask = LaneMask(120, 130, 9);
  cv::Mat expected, got;
  cv::erode(mask, expected, wide);
  detail::ErodeBinary(mask, wide, &got);
  EXPECT_EQ(cv::countNonZero(expected != got), 0);
}

TEST(ErodeBinary, ElementsItCannotDoAreRefused) {
  cv::Mat out;
  const cv::Mat mask(10, 10, CV_8UC1, cv::Scalar(255));
  cv::Mat off_centre = cv::Mat::zeros(3, 3, CV_8UC1);
  off_centre.at<std::uint8_t>(1, 2) = 1;
  EXPECT_THROW(detail::ErodeBinary(mask, off_centre, &out), core::Error);
  cv::Mat split = cv::Mat::ones(1, 5, CV_8UC1);
  split.at<std::uint8_t>(0, 1) = 0;
  split.at<std::uint8_t>(0, 3) = 0;
  EXPECT_THROW(detail::ErodeBinary(mask, split, &out), core::Error);
  EXPECT_THROW(detail::ErodeBinary(mask, cv::Mat::ones(2, 2, CV_8UC1), &out), core::Error);
}

}  // namespace
}  // namespace mosaicloc::tracking
