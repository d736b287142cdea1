#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "../src/area_halve.hpp"
#include "../src/simd.hpp"
#include "mosaicloc/core/error.hpp"

namespace mosaicloc::tracking {
namespace {

// The frame's 2x2 average is OpenCV's INTER_AREA halving, pixel for pixel, in both builds; odd
// sides go to OpenCV itself.
TEST(Templates, HalvingEqualsOpenCvsAreaResize) {
  for (const cv::Size size : {cv::Size(640, 480), cv::Size(98, 34), cv::Size(66, 2), cv::Size(97, 35)}) {
    cv::Mat image(size, CV_8UC1);
    cv::RNG(37).fill(image, cv::RNG::UNIFORM, 0, 256);
    cv::Mat expected, plain, vector;
    cv::resize(image, expected, cv::Size(size.width / 2, size.height / 2), 0, 0, cv::INTER_AREA);
    detail::SetAvx2Allowed(false);
    detail::HalveImage(image, plain);
    detail::SetAvx2Allowed(true);
    detail::HalveImage(image(cv::Rect(0, 0, size.width, size.height)), vector);
    ASSERT_EQ(plain.size(), expected.size());
    EXPECT_EQ(cv::norm(plain, expected, cv::NORM_INF), 0.0) << size;
    EXPECT_EQ(cv::norm(vector, expected, cv::NORM_INF), 0.0) << size;
  }
  cv::Mat out;
  EXPECT_THROW(detail::HalveImage(cv::Mat(1, 1, CV_8UC1), out), core::Error);
}

}  // namespace
}  // namespace mosaicloc::tracking
