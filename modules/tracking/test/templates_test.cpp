#include <algorithm>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "../src/ranking_map.hpp"
#include "../src/simd.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/tracking/templates.hpp"
#include "tracking_test_support.hpp"

namespace mosaicloc::tracking {
namespace {

TEST(Templates, SpreadPicksTexturedWindowsInDistinctCells) {
  cv::Mat frame(480, 640, CV_8UC1, cv::Scalar(128));
  cv::Mat noise(480, 240, CV_8UC1);
  cv::RNG(3).fill(noise, cv::RNG::UNIFORM, 0, 256);
  noise.copyTo(frame(cv::Rect(400, 0, 240, 480)));  // only the right part has texture
  TemplateOptions options;
  options.count = 4;
  const std::vector<TemplateSpot> spots = SelectTemplates(frame, options);
  ASSERT_EQ(spots.size(), 2u) << "the two cells of the blank half must give nothing";
  for (const TemplateSpot& spot : spots) {
    EXPECT_GE(spot.rect.x + spot.rect.width, 400 + 40) << "a template sits on the blank part";
    EXPECT_EQ(spot.rect.width, 96);
    EXPECT_GT(spot.texture, options.min_texture);
  }
  EXPECT_NE(spots[0].rect.y, spots[1].rect.y);
}

// A frame textured in one spot at its centre: the best window of every cell is the same one
// (the cells' ranges meet there). It is chosen once; no two windows cover each other by half.
TEST(Templates, OneTexturedSpotIsChosenOnce) {
  cv::Mat frame(480, 640, CV_8UC1, cv::Scalar(128));
  cv::Mat noise(96, 96, CV_8UC1);
  cv::RNG(5).fill(noise, cv::RNG::UNIFORM, 0, 256);
  noise.copyTo(frame(cv::Rect(272, 192, 96, 96)));
  TemplateOptions options;
  options.count = 4;
  options.min_texture = 0.0;
  const std::vector<TemplateSpot> spots = SelectTemplates(frame, options);
  ASSERT_FALSE(spots.empty());
  EXPECT_EQ(spots[0].rect, cv::Rect(272, 192, 96, 96));
  for (std::size_t i = 0; i < spots.size(); ++i) {
    for (std::size_t j = 0; j < i; ++j) {
      EXPECT_LE((spots[i].rect & spots[j].rect).area() * 2, spots[i].rect.area())
          << "templates " << j << " and " << i << " at " << spots[i].rect.x << "," << spots[i].rect.y;
    }
  }
}

// The templates SelectTemplates should choose, from the ranking map as OpenCV computes it
// (RankingMapOpenCv: 2x2 area average, Sobel with scale 1/8, products area-averaged into
// 8 px cells, box filter over a template), to check its exact integer version against: the
// same template in every cell.
std::vector<cv::Rect> OpenCvRanking(const cv::Mat& frame, const TemplateOptions& options, cv::Size grid) {
  cv::Mat half, eigen;
  cv::resize(frame, half, cv::Size(frame.cols / 2, frame.rows / 2), 0, 0, cv::INTER_AREA);
  const int s = options.size_px & ~1, b = (options.border_px + 1) & ~1, k = std::max(1, s / 8);
  detail::RankingMapOpenCv(half, k, &eigen);
  const cv::Size cells = eigen.size();
  const int max_x = (frame.cols - b - s) & ~1, max_y = (frame.rows - b - s) & ~1;
  std::vector<cv::Rect> rects;
  for (int gr = 0; gr < grid.height; ++gr) {
    for (int gc = 0; gc < grid.width; ++gc) {
      if (gr * grid.width + gc >= options.count) break;
      const int x_lo = std::clamp(gc * frame.cols / grid.width - s / 2, b, max_x);
      const int x_hi = std::clamp((gc + 1) * frame.cols / grid.width - s / 2, b, max_x);
      const int y_lo = std::clamp(gr * frame.rows / grid.height - s / 2, b, max_y);
      const int y_hi = std::clamp((gr + 1) * frame.rows / grid.height - s / 2, b, max_y);
      double best = -1.0;
      std::optional<cv::Rect> chosen;
      for (int y = y_lo; y <= y_hi; y += 8) {
        for (int x = x_lo; x <= x_hi; x += 8) {
          const int sx = std::min(x / 8, cells.width - 1), sy = std::min(y / 8, cells.height - 1);
          const double e = eigen.at<double>(sy, sx);
          const cv::Rect candidate(x & ~1, y & ~1, s, s);
          // Not more than half covered by a window another cell chose.
          const bool taken = std::any_of(rects.begin(), rects.end(), [&](const cv::Rect& r) {
            return (candidate & r).area() * 2 > candidate.area();
          });
          if (e > best && !taken) {
            best = e;
            chosen = candidate;
          }
        }
      }
      if (chosen) rects.push_back(*chosen);
    }
  }
  return rects;
}

TEST(Templates, RankingEqualsOpenCvsAndTextureItsStrength) {
  cv::Mat noise(480, 640, CV_8UC1);
  cv::RNG(17).fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(noise, noise, cv::Size(0, 0), 2.0);
  std::vector<cv::Mat> frames = {noise};
  if (const std::optional<cv::Mat> texture = Asphalt()) {
    const Scene scene(*texture);
    for (const double yaw_deg : {0.0, 17.0, 45.0}) frames.push_back(scene.Frame(Pose2(3.0, -2.0, yaw_deg * kDeg), 2.0));
  }
  for (const int count : {4, 8, 6}) {
    TemplateOptions options;
    options.count = count;
    options.min_texture = 0.0;
    const std::vector<std::pair<int, int>> grids = {{2, 2}, {4, 2}, {3, 2}};
    const cv::Size grid(grids[count == 4 ? 0 : count == 8 ? 1 : 2].first, grids[count == 4 ? 0 : count == 8 ? 1 : 2].second);
    for (const cv::Mat& frame : frames) {
      const std::vector<TemplateSpot> spots = SelectTemplates(frame, options);
      const std::vector<cv::Rect> expected = OpenCvRanking(frame, options, grid);
      ASSERT_EQ(spots.size(), expected.size()) << count;
      cv::Mat half;
      cv::resize(frame, half, cv::Size(frame.cols / 2, frame.rows / 2), 0, 0, cv::INTER_AREA);
      for (std::size_t i = 0; i < spots.size(); ++i) {
        EXPECT_EQ(spots[i].rect, expected[i]) << "count " << count << " template " << i;
        const cv::Rect& r = spots[i].rect;
        const double strength = TextureStrength(half(cv::Rect(r.x / 2, r.y / 2, r.width / 2, r.height / 2)));
        EXPECT_NEAR(spots[i].texture, strength, 1e-5 * strength);
      }
    }
  }
}

// The exact integer ranking map is OpenCV's, bit for bit, at every template size.
TEST(Templates, IntegerRankingMapIsOpenCvsExactly) {
  cv::Mat frame(480, 640, CV_8UC1), half;
  cv::RNG(29).fill(frame, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(frame, frame, cv::Size(0, 0), 1.0);
  cv::resize(frame, half, cv::Size(frame.cols / 2, frame.rows / 2), 0, 0, cv::INTER_AREA);
  for (const int k : {1, 4, 12, 16}) {
    cv::Mat exact, opencv;
    detail::RankingMap(half, k, &exact);
    detail::RankingMapOpenCv(half, k, &opencv);
    ASSERT_EQ(exact.size(), opencv.size()) << "k " << k;
    EXPECT_EQ(cv::norm(exact, opencv, cv::NORM_INF), 0.0) << "k " << k;
  }
}

// A frame whose halves do not halve evenly takes OpenCV's own pipeline; it must select alike.
TEST(Templates, RankingOfAnUnevenFrameEqualsOpenCvs) {
  cv::Mat frame(470, 628, CV_8UC1);
  cv::RNG(23).fill(frame, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(frame, frame, cv::Size(0, 0), 1.5);
  TemplateOptions options;
  options.min_texture = 0.0;
  const std::vector<TemplateSpot> spots = SelectTemplates(frame, options);
  const std::vector<cv::Rect> expected = OpenCvRanking(frame, options, cv::Size(2, 2));
  ASSERT_EQ(spots.size(), expected.size());
  for (std::size_t i = 0; i < spots.size(); ++i) EXPECT_EQ(spots[i].rect, expected[i]) << "template " << i;
}

// TextureStrength as OpenCV's Sobel and dot products give it (they sum in float, so to a
// relative 1e-6): inside an image (neighbours read beyond the region), at its edges
// (reflected) and with odd sides.
TEST(Templates, TextureStrengthEqualsOpenCvsOnRegionsAndWholeImages) {
  cv::Mat image(101, 133, CV_8UC1);
  cv::RNG(29).fill(image, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(image, image, cv::Size(0, 0), 1.2);
  const auto opencv = [](const cv::Mat& region) {
    cv::Mat gx, gy;
    cv::Sobel(region, gx, CV_32F, 1, 0, 3, 0.125);
    cv::Sobel(region, gy, CV_32F, 0, 1, 3, 0.125);
    const double n = static_cast<double>(region.total());
    const double a = gx.dot(gx) / n, b = gx.dot(gy) / n, c = gy.dot(gy) / n;
    return 0.5 * (a + c) - std::sqrt(0.25 * (a - c) * (a - c) + b * b);
  };
  for (const cv::Rect& rect : {cv::Rect(10, 12, 48, 48), cv::Rect(0, 0, 37, 29), cv::Rect(96, 64, 37, 37),
                               cv::Rect(1, 1, 131, 99), cv::Rect(0, 0, 133, 101), cv::Rect(50, 40, 1, 1)}) {
    const cv::Mat region = image(rect);
    const double expected = opencv(region);
    EXPECT_NEAR(TextureStrength(region), expected, 1e-6 * std::abs(expected) + 1e-9)
        << rect.x << "," << rect.y << " " << rect.width << "x" << rect.height;
    // The same pixels as an image of their own: the edges are reflected, not read beyond.
    EXPECT_NEAR(TextureStrength(region.clone()), opencv(region.clone()), 1e-6 * std::abs(expected) + 1e-9);
  }
  EXPECT_THROW(TextureStrength(cv::Mat()), core::Error);
}

TEST(Templates, VectorBuildsAgreeExactly) {
  cv::Mat frame(480, 640, CV_8UC1);
  cv::RNG(31).fill(frame, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(frame, frame, cv::Size(0, 0), 1.0);
  for (const int count : {4, 9}) {
    TemplateOptions options;
    options.count = count;
    options.min_texture = 0.0;
    detail::SetAvx2Allowed(false);
    const std::vector<TemplateSpot> plain = SelectTemplates(frame, options);
    detail::SetAvx2Allowed(true);
    const std::vector<TemplateSpot> vector = SelectTemplates(frame, options);
    ASSERT_EQ(plain.size(), vector.size());
    for (std::size_t i = 0; i < plain.size(); ++i) {
      EXPECT_EQ(plain[i].rect, vector[i].rect);
      EXPECT_EQ(plain[i].texture, vector[i].texture);
    }
  }
}

TEST(Templates, TiledCoversTheFrame) {
  cv::Mat frame(480, 640, CV_8UC1);
  cv::RNG(4).fill(frame, cv::RNG::UNIFORM, 0, 256);
  TemplateOptions options;
  options.mode = TemplateMode::kTiled;
  const std::vector<TemplateSpot> spots = SelectTemplates(frame, options);
  ASSERT_EQ(spots.size(), 12u);
  int area = 0;
  for (const TemplateSpot& s : spots) area += s.rect.area();
  const int b = options.border_px;
  EXPECT_GT(area, 0.97 * (640 - 2 * b) * (480 - 2 * b)) << "everything inside the border is used";
  for (std::size_t i = 0; i < spots.size(); ++i) {
    for (std::size_t j = i + 1; j < spots.size(); ++j) EXPECT_EQ((spots[i].rect & spots[j].rect).area(), 0);
  }
}

TEST(Templates, RejectsBadOptions) {
  TemplateOptions options;
  options.size_px = 4;
  std::string why;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_NE(why.find("size_px"), std::string::npos);
  cv::Mat frame(480, 640, CV_8UC1, cv::Scalar(0));
  EXPECT_THROW(SelectTemplates(frame, options), core::Error);
}

}  // namespace
}  // namespace mosaicloc::tracking
