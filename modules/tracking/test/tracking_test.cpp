#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <random>

#include <ceres/ceres.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "../src/area_halve.hpp"
#include "../src/simd.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/mosaic/tile_cache.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"
#include "mosaicloc/sim/resample.hpp"
#include "mosaicloc/test/test_support.hpp"
#include "mosaicloc/tracking/render_window.hpp"
#include "mosaicloc/tracking/tracker.hpp"

namespace mosaicloc::tracking {
namespace {

using core::Pose2;
using Affine = Eigen::Matrix<double, 2, 3>;
constexpr double kMmPerPx = 0.25;
constexpr double kDeg = std::numbers::pi / 180.0;

// A reference image cut from a real texture and live frames of it at exactly known poses.
// The texture is sampled at half resolution (2x2 area average of exact bicubic samples), like
// a camera seeing a continuous floor. The world frame is the reference image's camera frame.
class Scene {
 public:
  explicit Scene(cv::Mat texture, cv::Size reference_size = {960, 800})
      : texture_(std::move(texture)), camera_(camera::IdealCameraOptions{}) {
    source_from_reference_ << 2.0, 0.0, 0.5 + 40.0, 0.0, 2.0, 0.5 + 40.0;
    cv::Mat exact = sim::ResampleExact(texture_, source_from_reference_, reference_size, 2);
    exact.convertTo(reference_image_, CV_8UC1);
    reference_ = std::make_unique<ImageReference>(reference_image_, Pose2::Identity(), kMmPerPx);
  }

  // The live frame at world_from_camera, with gain, offset and Gaussian noise.
  cv::Mat Frame(const Pose2& world_from_camera, double noise = 0.0, double gain = 1.0, double offset = 0.0,
                std::uint64_t seed = 1) const {
    const Affine reference_from_view =
        ComposeAffine(reference_->WorldToRaster(), camera_.PixelToWorldAffine(world_from_camera));
    cv::Mat exact = sim::ResampleExact(texture_, ComposeAffine(source_from_reference_, reference_from_view),
                                       cv::Size(camera_.width_px(), camera_.height_px()), 2);
    exact = exact * gain + offset;
    if (noise > 0.0) {
      cv::Mat n(exact.size(), CV_32FC1);
      cv::RNG rng(seed);
      rng.fill(n, cv::RNG::NORMAL, 0.0, noise);
      exact += n;
    }
    cv::Mat frame;
    exact.convertTo(frame, CV_8UC1);
    return frame;
  }

  const camera::IdealCamera& camera() const { return camera_; }
  const ImageReference& reference() const { return *reference_; }
  const cv::Mat& reference_image() const { return reference_image_; }

 private:
  cv::Mat texture_;
  camera::IdealCamera camera_;
  Affine source_from_reference_;
  cv::Mat reference_image_;
  std::unique_ptr<ImageReference> reference_;
};

std::optional<cv::Mat> Asphalt() {
  const auto file = test::SharedTexture("asphalt_02_2048.jpg");
  if (!file) return std::nullopt;
  return cv::imread(file->string(), cv::IMREAD_GRAYSCALE);
}

#define REQUIRE_ASPHALT(texture)                                   \
  const std::optional<cv::Mat> texture = Asphalt();                \
  if (!texture) GTEST_SKIP() << test::SharedDataMissingMessage();

// Every template's fate, for failure messages.
std::string Describe(const TrackResult& r) {
  std::string text = r.reason;
  for (const TemplateReport& t : r.templates) {
    text += "\n  template at " + std::to_string(t.spot.rect.x) + "," + std::to_string(t.spot.rect.y) +
            ": range " + std::to_string(t.search_range_px) + " peak " + std::to_string(t.coarse.peak) +
            " ambiguity " + std::to_string(t.coarse.ambiguity) + " refined zncc " + std::to_string(t.refined.zncc) +
            " " + (t.rejected.empty() ? "used" : t.rejected);
  }
  return text;
}

Eigen::Matrix3d PriorCovariance(double sigma_px, double sigma_deg) {
  return Eigen::Vector3d(std::pow(sigma_px * kMmPerPx, 2), std::pow(sigma_px * kMmPerPx, 2),
                         std::pow(sigma_deg * kDeg, 2))
      .asDiagonal();
}

// ---------------------------------------------------------------------------------------
// Templates

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

// The ranking as OpenCV computes it (2x2 area average, Sobel with scale 1/8, products
// area-averaged into 8 px cells, box filter over a template), to check SelectTemplates' exact
// integer version against: the same template in every cell.
std::vector<cv::Rect> OpenCvRanking(const cv::Mat& frame, const TemplateOptions& options, cv::Size grid) {
  cv::Mat half, quarter, gx, gy, product, sxx, sxy, syy, mxx, mxy, myy;
  cv::resize(frame, half, cv::Size(frame.cols / 2, frame.rows / 2), 0, 0, cv::INTER_AREA);
  cv::resize(half, quarter, cv::Size(half.cols / 2, half.rows / 2), 0, 0, cv::INTER_AREA);
  cv::Sobel(quarter, gx, CV_32F, 1, 0, 3, 0.125);
  cv::Sobel(quarter, gy, CV_32F, 0, 1, 3, 0.125);
  const cv::Size cells(quarter.cols / 2, quarter.rows / 2);
  cv::multiply(gx, gx, product);
  cv::resize(product, sxx, cells, 0, 0, cv::INTER_AREA);
  cv::multiply(gx, gy, product);
  cv::resize(product, sxy, cells, 0, 0, cv::INTER_AREA);
  cv::multiply(gy, gy, product);
  cv::resize(product, syy, cells, 0, 0, cv::INTER_AREA);
  const int s = options.size_px & ~1, b = (options.border_px + 1) & ~1, k = std::max(1, s / 8);
  cv::boxFilter(sxx, mxx, -1, cv::Size(k, k), cv::Point(0, 0), true, cv::BORDER_REPLICATE);
  cv::boxFilter(sxy, mxy, -1, cv::Size(k, k), cv::Point(0, 0), true, cv::BORDER_REPLICATE);
  cv::boxFilter(syy, myy, -1, cv::Size(k, k), cv::Point(0, 0), true, cv::BORDER_REPLICATE);
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
          const double a = mxx.at<float>(sy, sx), m = mxy.at<float>(sy, sx), c = myy.at<float>(sy, sx);
          const double e = 0.5 * (a + c) - std::sqrt(0.25 * (a - c) * (a - c) + m * m);
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

// A frame whose halves do not halve evenly takes OpenCV's own pipeline; it must rank alike.
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

// ---------------------------------------------------------------------------------------
// ZNCC search

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

// ---------------------------------------------------------------------------------------
// Reference rasters

TEST(Reference, ImageReferenceGeometryMatchesTheIdealCamera) {
  cv::Mat image(480, 640, CV_8UC1, cv::Scalar(7));
  const Pose2 world_from_camera(100.0, -50.0, 0.3);
  const ImageReference reference(image, world_from_camera, kMmPerPx);
  const camera::IdealCamera camera{camera::IdealCameraOptions{}};
  for (const Eigen::Vector2d& pixel :
       {Eigen::Vector2d(0, 0), Eigen::Vector2d(639, 479), Eigen::Vector2d(12.5, 300.25)}) {
    const Eigen::Vector2d expected = camera.PixelToWorld(pixel, world_from_camera);
    const Affine a = reference.RasterToWorld();
    EXPECT_NEAR((a.leftCols<2>() * pixel + a.col(2) - expected).norm(), 0.0, 1e-9);
    const Affine b = reference.WorldToRaster();
    EXPECT_NEAR((b.leftCols<2>() * expected + b.col(2) - pixel).norm(), 0.0, 1e-9);
  }
  EXPECT_NEAR(reference.mm_per_px(), kMmPerPx, 1e-12);
  const mosaic::RasterPatch outside = reference.Region(630, 470, 20, 20);
  EXPECT_FALSE(outside.all_mapped);
  EXPECT_EQ(cv::countNonZero(outside.mask), 100);
}

TEST(Reference, RenderWindowAtIdentityIsTheImage) {
  cv::Mat image(100, 120, CV_8UC1);
  cv::RNG(7).fill(image, cv::RNG::UNIFORM, 0, 256);
  const ImageReference reference(image, Pose2::Identity(), 1.0);
  Affine identity;
  identity << 1, 0, 0, 0, 1, 0;
  cv::Mat mask;
  const cv::Mat window = RenderWindow(reference, identity, cv::Point(10, 20), cv::Size(50, 40), &mask);
  EXPECT_EQ(cv::norm(window, image(cv::Rect(10, 20, 50, 40)), cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::countNonZero(mask), 50 * 40);
}

// The AVX2 build of the unchecked path (when the processor has it) renders the same pixels
// as the baseline build, at widths that are and are not whole groups of four.
TEST(Reference, RenderWindowVectorBuildsAgreeExactly) {
  cv::Mat image(200, 220, CV_8UC1);
  cv::RNG(13).fill(image, cv::RNG::UNIFORM, 0, 256);
  const ImageReference reference(image, Pose2::Identity(), 1.0);
  Affine frame_to_raster;
  const double c = std::cos(0.7), s = std::sin(0.7);
  frame_to_raster << 0.5 * c, -0.5 * s, 90.3, 0.5 * s, 0.5 * c, 30.7;
  for (const cv::Size size : {cv::Size(60, 60), cv::Size(57, 33)}) {
    const cv::Mat fast = RenderWindow(reference, frame_to_raster, cv::Point(5, 5), size);
    detail::SetAvx2Allowed(false);
    const cv::Mat plain = RenderWindow(reference, frame_to_raster, cv::Point(5, 5), size);
    detail::SetAvx2Allowed(true);
    EXPECT_EQ(cv::norm(fast, plain, cv::NORM_INF), 0.0);
  }
}

// Inside the reference (the unchecked path) and across its edge (the checked one) the window
// is the same bilinear interpolation, rounded, as written out here.
// A block fetched into a reused store equals the block with pixels of its own, whatever the
// store held before, and leaves the mask out exactly when every pixel is mapped: over fully
// mapped tiles, the mapped and unmapped parts of a partly mapped tile, and an absent tile.
void ExpectRegionsIntoAStoreMatch(const ReferenceRaster& reference, cv::Size extent, int seed) {
  std::mt19937 rng(static_cast<unsigned>(seed));
  std::uniform_int_distribution<int> size(1, 70);
  cv::Mat store;
  mosaic::RasterPatch patch;
  int all_mapped = 0, partly = 0;
  for (int i = 0; i < 300; ++i) {
    const int cols = size(rng), rows = size(rng);
    const int col0 = std::uniform_int_distribution<int>(-20, extent.width - cols + 20)(rng);
    const int row0 = std::uniform_int_distribution<int>(-20, extent.height - rows + 20)(rng);
    const mosaic::RasterPatch owned = reference.Region(col0, row0, cols, rows);
    reference.Region(col0, row0, cols, rows, store, &patch);
    ASSERT_EQ(patch.image.size(), cv::Size(cols, rows));
    EXPECT_EQ(cv::norm(patch.image, owned.image, cv::NORM_INF), 0.0) << col0 << "," << row0;
    EXPECT_EQ(patch.all_mapped, owned.all_mapped) << col0 << "," << row0;
    EXPECT_EQ(patch.all_mapped, cv::countNonZero(owned.mask) == cols * rows);
    if (patch.all_mapped) {
      EXPECT_TRUE(patch.mask.empty());
      ++all_mapped;
    } else {
      ASSERT_EQ(patch.mask.size(), cv::Size(cols, rows));
      EXPECT_EQ(cv::norm(patch.mask, owned.mask, cv::NORM_INF), 0.0) << col0 << "," << row0;
      ++partly;
    }
  }
  EXPECT_GT(all_mapped, 20);
  EXPECT_GT(partly, 20);
}

TEST(Reference, MapRegionIntoAStoreEqualsTheOwnedRegion) {
  test::ScratchDir dir;
  mosaic::MapGrid grid;
  grid.tile_size_px = 64;
  auto store = mosaic::TileStore::Create(dir / "r.mosaic", grid);
  std::vector<mosaic::TileWrite> tiles;
  for (int row = 0; row < 2; ++row) {
    for (int col = 0; col < 3; ++col) {
      if (row == 1 && col == 2) continue;  // absent
      cv::Mat pixels(64, 64, CV_8UC1);
      cv::RNG(static_cast<std::uint64_t>(1 + row * 3 + col)).fill(pixels, cv::RNG::UNIFORM, 1, 256);
      if (row == 0 && col == 1) pixels(cv::Rect(40, 0, 24, 20)).setTo(0);  // partly mapped
      tiles.push_back({mosaic::TileKey{0, col, row}, pixels});
    }
  }
  store->Write(tiles);
  mosaic::TileCache cache(*store);
  const mosaic::MapRenderer renderer(cache);
  ExpectRegionsIntoAStoreMatch(MapReference(renderer, 0), cv::Size(192, 128), 5);
}

TEST(Reference, ImageRegionIntoAStoreEqualsTheOwnedRegion) {
  cv::Mat image(90, 120, CV_8UC1);
  cv::RNG(8).fill(image, cv::RNG::UNIFORM, 1, 256);
  ExpectRegionsIntoAStoreMatch(ImageReference(image, Pose2::Identity(), kMmPerPx), image.size(), 6);
}

TEST(Reference, RenderWindowIsBilinearInsideAndAcrossTheEdge) {
  cv::Mat image(200, 220, CV_8UC1);
  cv::RNG(11).fill(image, cv::RNG::UNIFORM, 0, 256);
  const ImageReference reference(image, Pose2::Identity(), 1.0);
  Affine frame_to_raster;
  const double c = std::cos(0.3), s = std::sin(0.3);
  frame_to_raster << 0.9 * c, -0.9 * s, 60.3, 0.9 * s, 0.9 * c, 20.7;
  // Known pixels, and how many pixels differ from the expectation.
  const auto compare = [&](const cv::Point& origin, const cv::Size& size) {
    cv::Mat mask;
    const cv::Mat window = RenderWindow(reference, frame_to_raster, origin, size, &mask);
    int known = 0, wrong = 0;
    for (int y = 0; y < size.height; ++y) {
      for (int x = 0; x < size.width; ++x) {
        const Eigen::Vector2d r = ApplyAffine(frame_to_raster, Eigen::Vector2d(origin.x + x, origin.y + y));
        const int ix = static_cast<int>(std::floor(r.x())), iy = static_cast<int>(std::floor(r.y()));
        const bool inside = ix >= 0 && iy >= 0 && ix + 1 < image.cols && iy + 1 < image.rows;
        wrong += mask.at<std::uint8_t>(y, x) != (inside ? 255 : 0) ? 1 : 0;
        if (!inside) continue;
        ++known;
        const double fx = r.x() - ix, fy = r.y() - iy;
        const double v = (1 - fy) * ((1 - fx) * image.at<std::uint8_t>(iy, ix) + fx * image.at<std::uint8_t>(iy, ix + 1)) +
                         fy * ((1 - fx) * image.at<std::uint8_t>(iy + 1, ix) + fx * image.at<std::uint8_t>(iy + 1, ix + 1));
        wrong += std::abs(window.at<std::uint8_t>(y, x) - v) > 0.5 + 1e-9 ? 1 : 0;
      }
    }
    return std::pair<int, int>(known, wrong);
  };
  const auto [inside_known, inside_wrong] = compare(cv::Point(10, 10), cv::Size(70, 60));
  EXPECT_EQ(inside_known, 70 * 60);
  EXPECT_EQ(inside_wrong, 0);
  const auto [edge_known, edge_wrong] = compare(cv::Point(-80, 40), cv::Size(90, 90));
  EXPECT_GT(edge_known, 0);
  EXPECT_LT(edge_known, 90 * 90);
  EXPECT_EQ(edge_wrong, 0);
}

// ---------------------------------------------------------------------------------------
// Pose solver

TEST(PoseSolver, AnalyticJacobianMatchesNumeric) {
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> u(-100.0, 100.0);
  for (int trial = 0; trial < 20; ++trial) {
    Correspondence c;
    c.camera_mm = {u(rng), u(rng)};
    c.world_mm = {u(rng), u(rng)};
    const double pose[3] = {u(rng), u(rng), u(rng) * 0.03};
    const double scale = 0.5 + std::abs(u(rng)) / 100.0;
    double r[2], j[6];
    PlanarResidual(pose, c, scale, r, j);
    for (int p = 0; p < 3; ++p) {
      const double h = 1e-6;
      double plus[3] = {pose[0], pose[1], pose[2]}, minus[3] = {pose[0], pose[1], pose[2]};
      plus[p] += h;
      minus[p] -= h;
      double rp[2], rm[2];
      PlanarResidual(plus, c, scale, rp, nullptr);
      PlanarResidual(minus, c, scale, rm, nullptr);
      for (int k = 0; k < 2; ++k) {
        EXPECT_NEAR(j[k * 3 + p], (rp[k] - rm[k]) / (2 * h), 1e-6) << "residual " << k << " parameter " << p;
      }
    }
  }
}

std::vector<Correspondence> MakeCorrespondences(const Pose2& truth, int n, double noise_mm, std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-80.0, 80.0);
  std::normal_distribution<double> g(0.0, noise_mm);
  std::vector<Correspondence> cs;
  for (int i = 0; i < n; ++i) {
    Correspondence c;
    c.camera_mm = {u(*rng), u(*rng) * 0.75};
    c.world_mm = truth * c.camera_mm + Eigen::Vector2d(g(*rng), g(*rng));
    c.sigma_mm = std::max(noise_mm, 1e-6);
    cs.push_back(c);
  }
  return cs;
}

TEST(PoseSolver, ThirtyPercentOutliersDoNotMoveThePose) {
  std::mt19937 rng(9);
  const Pose2 truth(1234.5, -678.9, 0.7);
  std::vector<Correspondence> cs = MakeCorrespondences(truth, 20, 0.0, &rng);
  const PoseSolution clean = SolvePlanarPose(cs, Pose2(1234.0, -679.5, 0.69), PoseSolverOptions{});
  ASSERT_TRUE(clean.ok());
  std::uniform_real_distribution<double> wild(-5.0, 5.0);
  for (int i = 0; i < 6; ++i)
    cs[static_cast<std::size_t>(3 * i)].world_mm += Eigen::Vector2d(wild(rng), wild(rng)) + Eigen::Vector2d(1.0, 0.0);
  const PoseSolution solution = SolvePlanarPose(cs, Pose2(1234.0, -679.5, 0.69), PoseSolverOptions{});
  ASSERT_TRUE(solution.ok()) << ToString(solution.failure);
  EXPECT_LT(Distance(solution.world_from_camera, truth), 0.01);
  EXPECT_LT(std::abs(YawDifference(solution.world_from_camera, truth)), 1e-5);
  EXPECT_EQ(solution.inliers, 14);
  for (int i = 0; i < 6; ++i) EXPECT_FALSE(solution.inlier[static_cast<std::size_t>(3 * i)]);
}

TEST(PoseSolver, CovarianceFollowsTheNoise) {
  std::mt19937 rng(10);
  const Pose2 truth(10.0, 20.0, -0.2);
  // Empirical scatter over repeated noisy solves against the reported covariance.
  const double noise_mm = 0.01;
  double sum_sq = 0.0, reported = 0.0;
  const int trials = 200;
  for (int t = 0; t < trials; ++t) {
    const std::vector<Correspondence> cs = MakeCorrespondences(truth, 8, noise_mm, &rng);
    const PoseSolution s = SolvePlanarPose(cs, truth, PoseSolverOptions{});
    ASSERT_TRUE(s.ok());
    sum_sq += std::pow(s.world_from_camera.x_mm() - truth.x_mm(), 2);
    reported += s.covariance(0, 0);
  }
  const double ratio = std::sqrt(sum_sq / trials) / std::sqrt(reported / trials);
  EXPECT_NEAR(ratio, 1.0, 0.2);
}

// One correspondence as a Ceres cost, for comparisons with ceres::Solve and ceres::Covariance.
class PlanarCeresCost final : public ceres::SizedCostFunction<2, 3> {
 public:
  explicit PlanarCeresCost(const Correspondence& c) : c_(c) {}
  bool Evaluate(double const* const* p, double* r, double** j) const override {
    PlanarResidual(p[0], c_, 1.0, r, j != nullptr ? j[0] : nullptr);
    return true;
  }

 private:
  Correspondence c_;
};

ceres::LossFunction* CeresLoss(RobustLoss loss, double scale) {
  if (loss == RobustLoss::kHuber) return new ceres::HuberLoss(scale);
  if (loss == RobustLoss::kCauchy) return new ceres::CauchyLoss(scale);
  return nullptr;
}

// The reweighted rounds reach the optimum ceres::Solve reaches on the same robust problem,
// with a quarter of the correspondences off by several loss scales.
TEST(PoseSolver, OptimumEqualsCeresSolve) {
  std::mt19937 rng(15);
  const Pose2 truth(-812.0, 95.0, 1.1);
  for (const RobustLoss loss : {RobustLoss::kNone, RobustLoss::kHuber, RobustLoss::kCauchy}) {
    PoseSolverOptions options;
    options.loss = loss;
    options.outlier_threshold_mm = 10.0;  // keep every correspondence: compare the robust solve itself
    std::vector<Correspondence> cs = MakeCorrespondences(truth, 12, 0.02, &rng);
    for (std::size_t i = 0; i < cs.size(); i += 4) cs[i].world_mm += Eigen::Vector2d(0.3, -0.2);
    const Pose2 start(-811.6, 95.3, 1.098);
    const PoseSolution s = SolvePlanarPose(cs, start, options);
    ASSERT_TRUE(s.ok()) << ToString(s.failure);
    double pose[3] = {start.x_mm(), start.y_mm(), start.yaw_rad()};
    ceres::Problem problem;
    for (const Correspondence& c : cs) {
      problem.AddResidualBlock(new PlanarCeresCost(c), CeresLoss(loss, options.loss_scale_mm), pose);
    }
    ceres::Solver::Options solver_options;
    solver_options.function_tolerance = solver_options.parameter_tolerance = 1e-14;
    solver_options.gradient_tolerance = 1e-16;
    solver_options.max_num_iterations = 200;
    solver_options.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(solver_options, &problem, &summary);
    EXPECT_NEAR(s.world_from_camera.x_mm(), pose[0], 1e-8) << static_cast<int>(loss);
    EXPECT_NEAR(s.world_from_camera.y_mm(), pose[1], 1e-8) << static_cast<int>(loss);
    EXPECT_NEAR(s.world_from_camera.yaw_rad(), pose[2], 1e-10) << static_cast<int>(loss);
  }
}

// The covariance is ceres::Covariance's on the same problem at the solution: residuals near
// the loss scale, so the robust loss's correction of the Jacobian counts.
TEST(PoseSolver, CovarianceEqualsCeresCovariance) {
  std::mt19937 rng(14);
  const Pose2 truth(321.0, -45.0, 0.4);
  for (const RobustLoss loss : {RobustLoss::kNone, RobustLoss::kHuber, RobustLoss::kCauchy}) {
    PoseSolverOptions options;
    options.loss = loss;
    options.loss_scale_mm = 0.02;
    options.outlier_threshold_mm = 1.0;  // keep every correspondence
    const std::vector<Correspondence> cs = MakeCorrespondences(truth, 7, 0.03, &rng);
    const PoseSolution s = SolvePlanarPose(cs, truth, options);
    ASSERT_TRUE(s.ok());
    ASSERT_EQ(s.inliers, 7);
    double pose[3] = {s.world_from_camera.x_mm(), s.world_from_camera.y_mm(), s.world_from_camera.yaw_rad()};
    ceres::Problem problem;
    for (const Correspondence& c : cs) {
      problem.AddResidualBlock(new PlanarCeresCost(c), CeresLoss(loss, options.loss_scale_mm), pose);
    }
    ceres::Covariance::Options covariance_options;
    covariance_options.algorithm_type = ceres::DENSE_SVD;
    ceres::Covariance covariance(covariance_options);
    const std::vector<std::pair<const double*, const double*>> blocks = {{pose, pose}};
    ASSERT_TRUE(covariance.Compute(blocks, &problem));
    Eigen::Matrix<double, 3, 3, Eigen::RowMajor> expected;
    ASSERT_TRUE(covariance.GetCovarianceBlock(pose, pose, expected.data()));
    // Every sigma is the same, so the solver's unit is sigma^2.
    const Eigen::Matrix3d got = s.covariance / (0.03 * 0.03);
    EXPECT_LT((got - expected).norm(), 1e-9 * expected.norm()) << static_cast<int>(loss) << "\n"
                                                               << got << "\n" << expected;
  }
}

// Without the covariance the solve is the same; the covariance says it was not computed.
TEST(PoseSolver, SkippingTheCovarianceLeavesThePose) {
  std::mt19937 rng(12);
  const Pose2 truth(-4.0, 7.0, 0.3);
  const std::vector<Correspondence> cs = MakeCorrespondences(truth, 6, 0.01, &rng);
  PoseSolverOptions options;
  const PoseSolution with = SolvePlanarPose(cs, Pose2(-3.9, 7.05, 0.29), options);
  options.compute_covariance = false;
  const PoseSolution without = SolvePlanarPose(cs, Pose2(-3.9, 7.05, 0.29), options);
  ASSERT_TRUE(with.ok());
  ASSERT_TRUE(without.ok());
  EXPECT_EQ(with.world_from_camera.x_mm(), without.world_from_camera.x_mm());
  EXPECT_EQ(with.world_from_camera.y_mm(), without.world_from_camera.y_mm());
  EXPECT_EQ(with.world_from_camera.yaw_rad(), without.world_from_camera.yaw_rad());
  EXPECT_EQ(with.inlier, without.inlier);
  EXPECT_TRUE(with.covariance.allFinite());
  EXPECT_TRUE(without.covariance.array().isNaN().all());
}

// Correspondences all at one point of the frame fix the translation but not the yaw: the
// covariance says the yaw is unknown rather than exact.
TEST(PoseSolver, CorrespondencesAtOnePointLeaveTheYawUndetermined) {
  const Pose2 truth(5.0, -3.0, 0.1);
  std::vector<Correspondence> cs(4);
  for (Correspondence& c : cs) {
    c.camera_mm = {12.0, -7.0};
    c.world_mm = truth * c.camera_mm;
    c.sigma_mm = 0.001;
  }
  const PoseSolution s = SolvePlanarPose(cs, Pose2(5.1, -3.1, 0.1), PoseSolverOptions{});
  ASSERT_TRUE(s.ok()) << ToString(s.failure);
  EXPECT_LT((s.world_from_camera * cs[0].camera_mm - cs[0].world_mm).norm(), 1e-6);
  EXPECT_TRUE(std::isinf(s.covariance(2, 2))) << s.covariance;
  // Two distinct points determine it, with a finite variance.
  cs[1].camera_mm = {-30.0, 20.0};
  cs[1].world_mm = truth * cs[1].camera_mm;
  const PoseSolution two = SolvePlanarPose(cs, Pose2(5.1, -3.1, 0.1), PoseSolverOptions{});
  ASSERT_TRUE(two.ok());
  EXPECT_TRUE(two.covariance.allFinite()) << two.covariance;
  EXPECT_GT(two.covariance(2, 2), 0.0);
}

TEST(PoseSolver, SaysWhyItFailed) {
  std::mt19937 rng(11);
  const std::vector<Correspondence> two = MakeCorrespondences(Pose2(), 2, 0.0, &rng);
  EXPECT_EQ(SolvePlanarPose(two, Pose2(), PoseSolverOptions{}).failure, PoseFailure::kTooFewInliers);
  // Three correspondences that disagree by millimetres: nothing is an inlier of anything.
  std::vector<Correspondence> scattered = MakeCorrespondences(Pose2(), 3, 0.0, &rng);
  scattered[0].world_mm.x() += 3.0;
  scattered[1].world_mm.y() -= 3.0;
  EXPECT_EQ(SolvePlanarPose(scattered, Pose2(), PoseSolverOptions{}).failure, PoseFailure::kTooFewInliers);
}

// ---------------------------------------------------------------------------------------
// Refinement: ours and ViSP's, every method and warp

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

// ---------------------------------------------------------------------------------------
// The tracker

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

}  // namespace
}  // namespace mosaicloc::tracking
