#include <algorithm>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "../src/simd.hpp"
#include "mosaicloc/tracking/zncc_search.hpp"
#include "tracking_test_support.hpp"

namespace mosaicloc::tracking {
namespace {

TEST(ZnccSearch, FindsIntegerAndSubPixelOffsets) {
  cv::Mat window(200, 200, CV_8UC1);
  cv::RNG(5).fill(window, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(window, window, cv::Size(0, 0), 1.2);
  const cv::Mat templ = window(cv::Rect(57, 71, 64, 64)).clone();
  const SearchPeak peak = SearchZncc(templ, window, SearchOptions{});
  ASSERT_TRUE(peak.found);
  EXPECT_NEAR(peak.offset_px.x(), 57.0, 0.3);
  EXPECT_NEAR(peak.offset_px.y(), 71.0, 0.3);
  EXPECT_GT(peak.peak, 0.99);
  EXPECT_LT(peak.ambiguity, 0.6);
  EXPECT_GT(peak.sharpness, 0.2);
  EXPECT_GE(peak.coarsest_level, 2) << "a +-68 px range must go coarse-to-fine";
}

// Small searches (the in-lock case) correlate directly instead of through OpenCV: the peak,
// its sub-pixel place and the second peak must be OpenCV's TM_CCOEFF_NORMED ones, for
// template widths that fill SIMD vectors and ones that do not, and on a flat window.
TEST(ZnccSearch, DirectSearchEqualsOpenCv) {
  const std::optional<cv::Mat> texture = Asphalt();  // random texture where the shared data is absent
  cv::Mat image(300, 300, CV_8UC1);
  if (texture) {
    cv::resize((*texture)(cv::Rect(0, 0, 600, 600)), image, image.size(), 0, 0, cv::INTER_AREA);
  } else {
    cv::RNG(9).fill(image, cv::RNG::UNIFORM, 0, 256);
    cv::GaussianBlur(image, image, cv::Size(0, 0), 1.0);
  }
  SearchOptions options;
  options.prefilter_sigma_px = 0.0;  // compare the correlation itself
  int compared = 0;
  for (const cv::Size size : {cv::Size(48, 48), cv::Size(37, 29), cv::Size(96, 72)}) {
    for (const int range : {1, 4, 9, 16}) {
      for (const cv::Point at : {cv::Point(40, 50), cv::Point(130, 90), cv::Point(150, 170)}) {
        const cv::Mat templ = image(cv::Rect(at, size)).clone();
        // The window is offset from the template by a known shift inside the range.
        const cv::Point shift((range * 2) / 3, -range / 2);
        const cv::Mat window =
            image(cv::Rect(at.x + shift.x - range, at.y + shift.y - range, size.width + 2 * range, size.height + 2 * range));
        const SearchPeak peak = SearchZncc(templ, window, options);
        cv::Mat expected;
        cv::matchTemplate(window, templ, expected, cv::TM_CCOEFF_NORMED);
        double best = 0.0;
        cv::Point best_at;
        cv::minMaxLoc(expected, nullptr, &best, nullptr, &best_at);
        ASSERT_TRUE(peak.found);
        EXPECT_EQ(peak.coarsest_level, 0);
        EXPECT_NEAR(peak.peak, best, 1e-5) << size << " range " << range;
        // The sub-pixel place from OpenCV's scores by the same parabola.
        const auto vertex = [&](cv::Point d) {
          const cv::Point a = best_at - d, c = best_at + d;
          if (a.x < 0 || a.y < 0 || c.x >= expected.cols || c.y >= expected.rows) return 0.0;
          const double l = expected.at<float>(a), m = expected.at<float>(best_at), r = expected.at<float>(c);
          return std::clamp(0.5 * (l - r) / (l - 2.0 * m + r), -0.5, 0.5);
        };
        EXPECT_EQ(best_at, cv::Point(range - shift.x, range - shift.y));
        EXPECT_NEAR(peak.offset_px.x(), best_at.x + vertex({1, 0}), 1e-4);
        EXPECT_NEAR(peak.offset_px.y(), best_at.y + vertex({0, 1}), 1e-4);
        ++compared;
      }
    }
  }
  EXPECT_EQ(compared, 36);
  // Scores away from the peak, and the second peak, match too.
  const cv::Mat templ = image(cv::Rect(100, 100, 48, 48)).clone();
  const cv::Mat window = image(cv::Rect(88, 88, 72, 72));
  const SearchPeak peak = SearchZncc(templ, window, options);
  cv::Mat expected;
  cv::matchTemplate(window, templ, expected, cv::TM_CCOEFF_NORMED);
  cv::Mat dilated;
  cv::dilate(expected, dilated, cv::Mat());
  double second = -1.0;
  for (int y = 0; y < expected.rows; ++y) {
    for (int x = 0; x < expected.cols; ++x) {
      const float v = expected.at<float>(y, x);
      if (v >= dilated.at<float>(y, x) && (std::abs(y - 12) >= 2 || std::abs(x - 12) >= 2)) {
        second = std::max(second, static_cast<double>(v));
      }
    }
  }
  EXPECT_NEAR(peak.second, second, 1e-5);
  // A flat window has no match, as with OpenCV (whose scores there are 0).
  const cv::Mat flat(72, 72, CV_8UC1, cv::Scalar(90));
  EXPECT_FALSE(SearchZncc(templ, flat, options).found);
  cv::matchTemplate(flat, templ, expected, cv::TM_CCOEFF_NORMED);
  EXPECT_EQ(cv::norm(expected, cv::NORM_INF), 0.0);
}

// The AVX2 build of the direct correlation (when the processor has it) finds the same peak,
// second peak and sub-pixel place as the baseline build, bit for bit.
TEST(ZnccSearch, DirectVectorBuildsAgreeExactly) {
  cv::Mat image(200, 200, CV_8UC1);
  cv::RNG(5).fill(image, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(image, image, cv::Size(0, 0), 1.5);
  for (const cv::Size size : {cv::Size(48, 48), cv::Size(37, 29), cv::Size(20, 64)}) {
    const cv::Mat templ = image(cv::Rect(70, 60, size.width, size.height)).clone();
    const cv::Mat window = image(cv::Rect(61, 52, size.width + 14, size.height + 18));
    const SearchPeak fast = SearchZncc(templ, window, SearchOptions{});
    detail::SetAvx2Allowed(false);
    const SearchPeak plain = SearchZncc(templ, window, SearchOptions{});
    detail::SetAvx2Allowed(true);
    EXPECT_EQ(fast.found, plain.found);
    EXPECT_EQ(fast.offset_px, plain.offset_px);
    EXPECT_EQ(fast.peak, plain.peak);
    EXPECT_EQ(fast.second, plain.second);
    EXPECT_EQ(fast.sharpness, plain.sharpness);
  }
}

TEST(ZnccSearch, LeavesItsInputsUntouched) {
  cv::Mat window(120, 120, CV_8UC1);
  cv::RNG(15).fill(window, cv::RNG::UNIFORM, 0, 256);
  const cv::Mat window_before = window.clone();
  const cv::Mat templ = window(cv::Rect(20, 30, 64, 64));
  SearchOptions options;
  options.prefilter_sigma_px = 1.5;
  ASSERT_TRUE(SearchZncc(templ, window, options).found);
  EXPECT_EQ(cv::norm(window, window_before, cv::NORM_INF), 0.0);
}

TEST(ZnccSearch, RepeatingPatternIsAmbiguous) {
  cv::Mat cell(20, 20, CV_8UC1);
  cv::RNG(6).fill(cell, cv::RNG::UNIFORM, 0, 256);
  cv::Mat window;
  cv::repeat(cell, 8, 8, window);
  const SearchPeak peak = SearchZncc(window(cv::Rect(30, 30, 64, 64)).clone(), window(cv::Rect(0, 0, 130, 130)),
                                     SearchOptions{});
  ASSERT_TRUE(peak.found);
  EXPECT_GT(peak.ambiguity, 0.99);
}

}  // namespace
}  // namespace mosaicloc::tracking
