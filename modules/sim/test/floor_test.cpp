#include "mosaicloc/sim/floor.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::sim {
namespace {

ProceduralFloorOptions Seeded(std::uint64_t seed) {
  ProceduralFloorOptions options;
  options.seed = seed;
  return options;
}

/// Number of texels that differ between two images of the same size.
int CountDifferent(const cv::Mat& a, const cv::Mat& b) {
  EXPECT_EQ(a.size(), b.size());
  EXPECT_EQ(a.type(), b.type());
  cv::Mat different;
  cv::compare(a, b, different, cv::CMP_NE);
  return cv::countNonZero(different);
}

/// The view of a 0.25 mm/px camera: texels at 0.125 mm averaged 2 x 2.
cv::Mat CameraResolution(const cv::Mat& texels) {
  cv::Mat camera;
  cv::resize(texels, camera, cv::Size(texels.cols / 2, texels.rows / 2), 0, 0, cv::INTER_AREA);
  return camera;
}

double MaxZncc(const cv::Mat& region, const cv::Mat& patch) {
  cv::Mat score;
  cv::matchTemplate(region, patch, score, cv::TM_CCOEFF_NORMED);
  double max_score = 0.0;
  cv::minMaxLoc(score, nullptr, &max_score);
  return max_score;
}

// --- options ---------------------------------------------------------------------------------

TEST(ProceduralFloorOptions, DefaultsAreValid) {
  std::string why;
  EXPECT_TRUE(ProceduralFloorOptions{}.Check(&why)) << why;
  EXPECT_TRUE(ProceduralFloorOptions{}.Check(nullptr));
}

TEST(ProceduralFloorOptions, CheckRejectsEachBadFieldByName) {
  struct Case {
    const char* field;
    void (*spoil)(ProceduralFloorOptions&);
  };
  const Case cases[] = {
      {"mm_per_texel", [](ProceduralFloorOptions& o) { o.mm_per_texel = 0.0; }},
      {"mm_per_texel", [](ProceduralFloorOptions& o) { o.mm_per_texel = -0.125; }},
      {"mm_per_texel",
       [](ProceduralFloorOptions& o) {
         o.mm_per_texel = std::numeric_limits<double>::quiet_NaN();
       }},
      {"matrix_dn", [](ProceduralFloorOptions& o) { o.matrix_dn = 300.0; }},
      {"grain_contrast_dn", [](ProceduralFloorOptions& o) { o.grain_contrast_dn = -1.0; }},
      {"stone_area_fraction", [](ProceduralFloorOptions& o) { o.stone_area_fraction = 2.0; }},
      {"stone_min_diameter_mm", [](ProceduralFloorOptions& o) { o.stone_min_diameter_mm = 0.0; }},
      {"stone_min_diameter_mm",
       [](ProceduralFloorOptions& o) {
         o.stone_min_diameter_mm = 6.0;
         o.stone_max_diameter_mm = 3.0;
       }},
      {"pore_density_per_cm2", [](ProceduralFloorOptions& o) { o.pore_density_per_cm2 = -0.1; }},
      {"stain_density_per_m2",
       [](ProceduralFloorOptions& o) {
         o.stain_density_per_m2 = std::numeric_limits<double>::infinity();
       }},
      {"crack_density_per_m2", [](ProceduralFloorOptions& o) { o.crack_density_per_m2 = 1e6; }},
      {"crack_max_length_mm", [](ProceduralFloorOptions& o) { o.crack_max_length_mm = 1.0; }},
      {"cache_bytes", [](ProceduralFloorOptions& o) { o.cache_bytes = 1000; }},
  };
  for (const Case& c : cases) {
    ProceduralFloorOptions options;
    c.spoil(options);
    std::string why;
    EXPECT_FALSE(options.Check(&why)) << c.field;
    EXPECT_NE(why.find(c.field), std::string::npos) << why;
    try {
      MakeProceduralFloor(options);
      ADD_FAILURE() << "no error for bad " << c.field;
    } catch (const core::Error& e) {
      EXPECT_EQ(e.kind(), core::ErrorKind::kInvalidInput);
      EXPECT_NE(std::string(e.what()).find(c.field), std::string::npos) << e.what();
    }
  }
}

// --- procedural floor ------------------------------------------------------------------------

TEST(ProceduralFloor, SameSeedGivesTheSameFloor) {
  const auto first = MakeProceduralFloor(Seeded(7));
  const auto second = MakeProceduralFloor(Seeded(7));
  EXPECT_DOUBLE_EQ(first->mm_per_texel(), 0.125);
  const cv::Mat a = first->Render(-300, -200, 700, 500);
  const cv::Mat b = second->Render(-300, -200, 700, 500);
  ASSERT_EQ(a.type(), CV_8UC1);
  ASSERT_EQ(a.size(), cv::Size(700, 500));
  EXPECT_EQ(CountDifferent(a, b), 0);
}

TEST(ProceduralFloor, DifferentSeedsGiveUnrelatedFloors) {
  const cv::Mat a = MakeProceduralFloor(Seeded(7))->Render(0, 0, 512, 512);
  const cv::Mat b = MakeProceduralFloor(Seeded(8))->Render(0, 0, 512, 512);
  cv::Mat difference;
  cv::absdiff(a, b, difference);
  EXPECT_GT(cv::mean(difference)[0], 15.0);
  EXPECT_LT(std::abs(MaxZncc(a, b)), 0.2);  // same size: a single correlation
}

TEST(ProceduralFloor, TexelDoesNotDependOnTheWindow) {
  const auto floor = MakeProceduralFloor(Seeded(3));
  // A fresh instance with the smallest cache renders every window from freshly generated,
  // often evicted tiles, in another order.
  ProceduralFloorOptions small_cache = Seeded(3);
  small_cache.cache_bytes = std::size_t{1} << 20;
  const auto fresh = MakeProceduralFloor(small_cache);

  const std::int64_t col0 = -700;
  const std::int64_t row0 = -520;
  const cv::Mat big = floor->Render(col0, row0, 1100, 900);
  std::mt19937 random(11);
  for (int trial = 0; trial < 60; ++trial) {
    const int cols = std::uniform_int_distribution<int>(1, 400)(random);
    const int rows = std::uniform_int_distribution<int>(1, 400)(random);
    const int x = std::uniform_int_distribution<int>(0, big.cols - cols)(random);
    const int y = std::uniform_int_distribution<int>(0, big.rows - rows)(random);
    const cv::Mat expected = big(cv::Rect(x, y, cols, rows));
    const auto& source = trial % 2 == 0 ? floor : fresh;
    const cv::Mat window = source->Render(col0 + x, row0 + y, cols, rows);
    ASSERT_EQ(CountDifferent(window, expected), 0)
        << "window " << cols << "x" << rows << " at (" << col0 + x << ", " << row0 + y << ")";
  }
}

TEST(ProceduralFloor, FarFromTheOriginItIsStillDeterministic) {
  const std::int64_t far = std::int64_t{1} << 36;  // 8600 km at 0.125 mm
  const cv::Mat a = MakeProceduralFloor(Seeded(5))->Render(far, -far, 300, 300);
  const cv::Mat b = MakeProceduralFloor(Seeded(5))->Render(far - 100, -far - 50, 400, 350);
  EXPECT_EQ(CountDifferent(a, b(cv::Rect(100, 50, 300, 300))), 0);
  cv::Scalar mean;
  cv::Scalar stddev;
  cv::meanStdDev(a, mean, stddev);
  EXPECT_GT(stddev[0], 20.0);
}

TEST(ProceduralFloor, ZeroAndNegativeSizes) {
  const auto floor = MakeProceduralFloor(Seeded(1));
  EXPECT_TRUE(floor->Render(5, 5, 0, 10).empty());
  EXPECT_TRUE(floor->Render(5, 5, 10, 0).empty());
  EXPECT_THROW(floor->Render(5, 5, -1, 10), std::invalid_argument);
}

TEST(ProceduralFloor, DescribeNamesSeedAndResolution) {
  ProceduralFloorOptions options = Seeded(7);
  options.crack_density_per_m2 = 2.5;
  const std::string text = MakeProceduralFloor(options)->Describe();
  EXPECT_EQ(text.rfind("procedural seed=7 mm_per_texel=0.125", 0), 0u) << text;
  EXPECT_NE(text.find("crack_density_per_m2=2.5"), std::string::npos) << text;
  EXPECT_EQ(text.find('\n'), std::string::npos);
}

TEST(ProceduralFloor, HasFullRangeContrast) {
  const cv::Mat texels = MakeProceduralFloor(Seeded(2))->Render(-1024, -1024, 2048, 2048);
  cv::Scalar mean;
  cv::Scalar stddev;
  cv::meanStdDev(texels, mean, stddev);
  EXPECT_GT(mean[0], 110.0);  // stains and mottling move the mean of a 256 mm window
  EXPECT_LT(mean[0], 150.0);
  EXPECT_GT(stddev[0], 25.0);
  EXPECT_LT(stddev[0], 45.0);
}

// A template tracker needs texture everywhere: no 64 x 64 camera patch (16 x 16 mm) may be
// flat, over a 0.5 m x 0.5 m sample of the floor. Gradient energy is checked too.
TEST(ProceduralFloor, NoBlankPatchAtCameraResolution) {
  const auto floor = MakeProceduralFloor(Seeded(4));
  double lowest_std = 1e9;
  double lowest_gradient = 1e9;
  for (int block_row = 0; block_row < 4; ++block_row) {
    for (int block_col = 0; block_col < 4; ++block_col) {
      const cv::Mat camera = CameraResolution(
          floor->Render(block_col * 1024 - 2048, block_row * 1024 - 2048, 1024, 1024));
      cv::Mat gx;
      cv::Mat gy;
      cv::Sobel(camera, gx, CV_32F, 1, 0);
      cv::Sobel(camera, gy, CV_32F, 0, 1);
      cv::Mat magnitude;
      cv::magnitude(gx, gy, magnitude);
      for (int y = 0; y + 64 <= camera.rows; y += 32) {
        for (int x = 0; x + 64 <= camera.cols; x += 32) {
          const cv::Rect patch(x, y, 64, 64);
          cv::Scalar mean;
          cv::Scalar stddev;
          cv::meanStdDev(camera(patch), mean, stddev);
          lowest_std = std::min(lowest_std, stddev[0]);
          lowest_gradient = std::min(lowest_gradient, cv::mean(magnitude(patch))[0]);
        }
      }
    }
  }
  std::printf("lowest patch std %.1f DN, lowest mean Sobel magnitude %.1f DN/px\n", lowest_std,
              lowest_gradient);
  EXPECT_GT(lowest_std, 12.0);
  EXPECT_GT(lowest_gradient, 40.0);
}

TEST(ProceduralFloor, TileBordersAreSeamless) {
  const auto floor = MakeProceduralFloor(Seeded(6));
  const cv::Mat texels = floor->Render(0, 0, 2048, 2048);
  cv::Mat f;
  texels.convertTo(f, CV_32F);
  const auto column_step = [&](int x) {  // mean |texel(x) - texel(x - 1)| down the image
    cv::Mat d;
    cv::absdiff(f.col(x), f.col(x - 1), d);
    return cv::mean(d)[0];
  };
  const auto row_step = [&](int y) {
    cv::Mat d;
    cv::absdiff(f.row(y), f.row(y - 1), d);
    return cv::mean(d)[0];
  };
  double border = 0.0;
  double inside = 0.0;
  int borders = 0;
  for (int t = 256; t < 2048; t += 256) {
    border += column_step(t) + row_step(t);
    // The lattices make step statistics depend on the position modulo 8 texels: compare
    // with mid-tile lines of the same phase.
    inside += column_step(t - 128) + row_step(t - 128) + column_step(t + 64) + row_step(t + 64);
    ++borders;
  }
  border /= 2 * borders;
  inside /= 4 * borders;
  EXPECT_LT(border, 1.05 * inside) << "border step " << border << " vs inside " << inside;
  EXPECT_GT(border, 0.95 * inside) << "border step " << border << " vs inside " << inside;
}

TEST(ProceduralFloor, DoesNotRepeat) {
  const auto floor = MakeProceduralFloor(Seeded(9));
  const cv::Mat patch = CameraResolution(floor->Render(4000, 4000, 256, 256));  // 128 x 128
  // Sanity: the patch is found where it is.
  const cv::Mat home = CameraResolution(floor->Render(3488, 3488, 1280, 1280));
  EXPECT_GT(MaxZncc(home, patch), 0.99);
  // Elsewhere, near and far, nothing looks like it.
  const std::int64_t far = 5'000'000;  // 625 m away
  for (const auto& [col, row] : std::vector<std::pair<std::int64_t, std::int64_t>>{
           {5000, 3000}, {-2000, 4000}, {far, 0}, {0, -far}, {-far, far}}) {
    const cv::Mat region = CameraResolution(floor->Render(col, row, 2048, 2048));
    EXPECT_LT(MaxZncc(region, patch), 0.5) << "region at (" << col << ", " << row << ")";
  }
}

TEST(ProceduralFloor, PhysicalFeaturesKeepTheirSizeAtAnotherResolution) {
  // Stones, pores, stains and cracks are placed in mm: a 0.25 mm/texel floor looks like the
  // 0.125 mm/texel floor averaged 2 x 2 (only the finest noise octaves differ).
  ProceduralFloorOptions coarse = Seeded(12);
  coarse.mm_per_texel = 0.25;
  const cv::Mat fine = CameraResolution(MakeProceduralFloor(Seeded(12))->Render(0, 0, 1024, 1024));
  const cv::Mat same = MakeProceduralFloor(coarse)->Render(0, 0, 512, 512);
  cv::Mat blurred_fine;
  cv::Mat blurred_same;
  cv::GaussianBlur(fine, blurred_fine, cv::Size(0, 0), 2.0);
  cv::GaussianBlur(same, blurred_same, cv::Size(0, 0), 2.0);
  EXPECT_GT(MaxZncc(blurred_fine, blurred_same), 0.5);
}

TEST(ProceduralFloor, CracksDarkenTheFloor) {
  ProceduralFloorOptions none = Seeded(10);
  none.crack_density_per_m2 = 0.0;
  ProceduralFloorOptions many = Seeded(10);
  many.crack_density_per_m2 = 40.0;
  const auto dark_fraction = [](const ProceduralFloorOptions& options) {
    const cv::Mat texels = MakeProceduralFloor(options)->Render(0, 0, 2048, 2048);
    return cv::countNonZero(texels < 35) / static_cast<double>(texels.total());
  };
  EXPECT_GT(dark_fraction(many), 2.0 * dark_fraction(none) + 0.002);
}

TEST(ProceduralFloor, ConcurrentRendersAgree) {
  ProceduralFloorOptions options = Seeded(13);
  options.cache_bytes = std::size_t{2} << 20;  // 32 tiles: threads evict each other's tiles
  const auto shared = MakeProceduralFloor(options);
  const cv::Mat reference = MakeProceduralFloor(Seeded(13))->Render(-1500, -1500, 3000, 3000);
  std::atomic<int> mismatches{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&, t] {
      std::mt19937 random(static_cast<unsigned>(100 + t));
      for (int n = 0; n < 25; ++n) {
        const int x = std::uniform_int_distribution<int>(0, 3000 - 700)(random);
        const int y = std::uniform_int_distribution<int>(0, 3000 - 500)(random);
        const cv::Mat window = shared->Render(x - 1500, y - 1500, 700, 500);
        cv::Mat different;
        cv::compare(window, reference(cv::Rect(x, y, 700, 500)), different, cv::CMP_NE);
        if (cv::countNonZero(different) != 0) ++mismatches;
      }
    });
  }
  for (std::thread& thread : threads) thread.join();
  EXPECT_EQ(mismatches.load(), 0);
}

// Figures for the simulator's budget; prints, never fails on time.
TEST(ProceduralFloor, ReportsGenerationAndRenderSpeed) {
  const auto floor = MakeProceduralFloor(Seeded(21));
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  constexpr int kSide = 2048;
  for (int k = 0; k < 4; ++k) floor->Render(k * kSide, 0, kSide, kSide);
  const double generate_s = std::chrono::duration<double>(Clock::now() - start).count();
  const auto cached_start = Clock::now();
  constexpr int kFrames = 50;
  for (int k = 0; k < kFrames; ++k) floor->Render(17 + k, 23, 1400, 1100);
  const double render_s = std::chrono::duration<double>(Clock::now() - cached_start).count();
  std::printf("tile generation %.1f Mtexel/s; cached 1400x1100 render %.2f ms (%.0f Mtexel/s)\n",
              4.0 * kSide * kSide / generate_s * 1e-6, render_s / kFrames * 1e3,
              1400.0 * 1100 * kFrames / render_s * 1e-6);
  SUCCEED();
}

// --- image floor -----------------------------------------------------------------------------

cv::Mat RandomImage(int cols, int rows, int type, unsigned seed) {
  cv::Mat image(rows, cols, type);
  cv::RNG random(seed);
  random.fill(image, cv::RNG::UNIFORM, 0, CV_MAT_DEPTH(type) == CV_16U ? 65536 : 256);
  return image;
}

TEST(ImageFloorOptions, CheckRejectsBadOptions) {
  ImageFloorOptions options;
  std::string why;
  EXPECT_FALSE(options.Check(&why));  // no file
  EXPECT_NE(why.find("image"), std::string::npos);
  options.image = "floor.png";
  EXPECT_TRUE(options.Check(&why)) << why;
  options.mm_per_texel = 0.0;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_NE(why.find("mm_per_texel"), std::string::npos);
  EXPECT_THROW(MakeImageFloor(options), core::Error);
}

TEST(ImageFloor, TilesThePlaneWithWrapAround) {
  const test::ScratchDir scratch;
  const cv::Mat image = RandomImage(40, 30, CV_8UC1, 1);
  ASSERT_TRUE(cv::imwrite((scratch / "floor.png").string(), image));
  ImageFloorOptions options;
  options.image = scratch / "floor.png";
  options.mm_per_texel = 0.5;
  const auto floor = MakeImageFloor(options);
  EXPECT_DOUBLE_EQ(floor->mm_per_texel(), 0.5);

  const std::int64_t col0 = -97;
  const std::int64_t row0 = -61;
  const cv::Mat window = floor->Render(col0, row0, 173, 111);
  ASSERT_EQ(window.size(), cv::Size(173, 111));
  for (int y = 0; y < window.rows; ++y) {
    for (int x = 0; x < window.cols; ++x) {
      const auto c = static_cast<int>(((col0 + x) % 40 + 40) % 40);
      const auto r = static_cast<int>(((row0 + y) % 30 + 30) % 30);
      ASSERT_EQ(window.at<std::uint8_t>(y, x), image.at<std::uint8_t>(r, c))
          << "texel (" << col0 + x << ", " << row0 + y << ")";
    }
  }
  EXPECT_EQ(CountDifferent(floor->Render(col0 + 40, row0 - 30, 173, 111), window), 0);
  EXPECT_EQ(CountDifferent(floor->Render(0, 0, 40, 30), image), 0);
  EXPECT_NE(floor->Describe().find("floor.png"), std::string::npos);
  EXPECT_NE(floor->Describe().find("mm_per_texel=0.5"), std::string::npos);
}

TEST(ImageFloor, ConvertsColourAndDeepImagesToEightBitGrey) {
  const test::ScratchDir scratch;
  const cv::Mat colour = RandomImage(32, 24, CV_8UC3, 2);
  ASSERT_TRUE(cv::imwrite((scratch / "colour.png").string(), colour));
  cv::Mat expected_grey;
  cv::cvtColor(colour, expected_grey, cv::COLOR_BGR2GRAY);
  ImageFloorOptions options;
  options.image = scratch / "colour.png";
  EXPECT_EQ(CountDifferent(MakeImageFloor(options)->Render(32, -24, 32, 24), expected_grey), 0);

  const cv::Mat deep = RandomImage(20, 20, CV_16UC1, 3);
  ASSERT_TRUE(cv::imwrite((scratch / "deep.png").string(), deep));
  options.image = scratch / "deep.png";
  const cv::Mat grey = MakeImageFloor(options)->Render(0, 0, 20, 20);
  ASSERT_EQ(grey.type(), CV_8UC1);
  for (int y = 0; y < 20; ++y) {
    for (int x = 0; x < 20; ++x) {
      EXPECT_NEAR(grey.at<std::uint8_t>(y, x), deep.at<std::uint16_t>(y, x) / 257.0, 0.51);
    }
  }
}

TEST(ImageFloor, UnreadableFilesAreNamedInTheError) {
  const test::ScratchDir scratch;
  test::WriteFile(scratch / "notes.png", "not an image");
  ASSERT_TRUE(cv::imwrite((scratch / "tiny.png").string(), RandomImage(8, 8, CV_8UC1, 4)));
  for (const std::string name : {"missing.png", "notes.png", "tiny.png"}) {
    ImageFloorOptions options;
    options.image = scratch / name;
    try {
      MakeImageFloor(options);
      ADD_FAILURE() << "no error for " << name;
    } catch (const core::Error& e) {
      EXPECT_EQ(e.kind(), core::ErrorKind::kInvalidInput);
      EXPECT_NE(std::string(e.what()).find(options.image.string()), std::string::npos) << e.what();
    }
  }
}

TEST(ImageFloor, RealAsphaltTextureRepeatsEvery2048Texels) {
  const auto file = test::SharedTexture("asphalt_02_2048.jpg");
  if (!file) GTEST_SKIP() << test::SharedDataMissingMessage();
  ImageFloorOptions options;
  options.image = *file;
  const auto floor = MakeImageFloor(options);
  const cv::Mat across_wrap = floor->Render(-300, 1900, 600, 300);
  EXPECT_EQ(CountDifferent(floor->Render(2048 - 300, 1900 - 2048, 600, 300), across_wrap), 0);
  cv::Scalar mean;
  cv::Scalar stddev;
  cv::meanStdDev(across_wrap, mean, stddev);
  EXPECT_GT(stddev[0], 10.0);
  EXPECT_NE(floor->Describe().find("size=2048x2048"), std::string::npos) << floor->Describe();
}

// A picture cut into patches: 64-texel squares blended over 16 texels, so that the 49 x 49
// texels around each square's centre (weight 1) are the picture's own, turned or mirrored.
ImageFloorOptions Patches(const std::filesystem::path& image) {
  ImageFloorOptions options;
  options.image = image;
  options.mm_per_texel = 0.5;
  options.layout = "patches";
  options.patch_mm = 32.0;
  options.seed = 5;
  return options;
}

TEST(ImageFloor, PatchesAreThePicturesOwnTexelsTurnedInTheirMiddlesAndTheFloorNeverRepeats) {
  const test::ScratchDir scratch;
  const cv::Mat image = RandomImage(200, 150, CV_8UC1, 6);
  ASSERT_TRUE(cv::imwrite((scratch / "floor.png").string(), image));
  const auto floor = MakeImageFloor(Patches(scratch / "floor.png"));
  const std::int64_t col0 = -150;
  const std::int64_t row0 = -90;
  const cv::Mat window = floor->Render(col0, row0, 400, 300);
  // The middle of every square whose middle is in the window is found in the picture, exactly.
  int squares = 0;
  std::vector<cv::Point> cut_at;
  for (std::int64_t j = -1; j <= 3; ++j) {
    for (std::int64_t i = -2; i <= 3; ++i) {
      const cv::Rect middle(static_cast<int>(i * 64 - 24 - col0), static_cast<int>(j * 64 - 24 - row0), 49, 49);
      if ((middle & cv::Rect(0, 0, window.cols, window.rows)) != middle) continue;
      // Turned back by each of the square's eight symmetries, one is found exactly.
      std::optional<cv::Point> found;
      for (int symmetry = 0; symmetry < 8 && !found; ++symmetry) {
        cv::Mat turned = window(middle).clone();
        if (symmetry & 4) cv::transpose(turned, turned);
        if (symmetry & 3) cv::flip(turned, turned, (symmetry & 3) == 1 ? 1 : (symmetry & 3) == 2 ? 0 : -1);
        cv::Mat distance;
        cv::matchTemplate(image, turned, distance, cv::TM_SQDIFF);
        cv::Point at;
        cv::minMaxLoc(distance, nullptr, nullptr, &at);  // the DFT's rounding: not exactly 0
        if (CountDifferent(image(cv::Rect(at.x, at.y, 49, 49)), turned) == 0) found = at;
      }
      ASSERT_TRUE(found) << "square (" << i << ", " << j << ") is not in the picture";
      cut_at.push_back(*found);
      ++squares;
    }
  }
  EXPECT_GE(squares, 20);
  // ... from places that differ from square to square (not one picture tiled).
  std::sort(cut_at.begin(), cut_at.end(), [](cv::Point a, cv::Point b) { return a.x != b.x ? a.x < b.x : a.y < b.y; });
  EXPECT_GE(std::unique(cut_at.begin(), cut_at.end()) - cut_at.begin(), squares - 2);
  // No period of the picture's size, and the blend keeps its mean and spread.
  EXPECT_GT(CountDifferent(floor->Render(col0 + 200, row0, 400, 300), window), 400 * 300 / 2);
  EXPECT_GT(CountDifferent(floor->Render(col0, row0 + 150, 400, 300), window), 400 * 300 / 2);
  cv::Scalar picture_mean;
  cv::Scalar picture_spread;
  cv::meanStdDev(image, picture_mean, picture_spread);
  cv::Scalar mean;
  cv::Scalar spread;
  cv::meanStdDev(window, mean, spread);
  EXPECT_NEAR(mean[0], picture_mean[0], 2.0);
  EXPECT_NEAR(spread[0], picture_spread[0], 0.05 * picture_spread[0]);
  // A texel is the same whatever window it is rendered in, and the same seed gives the same floor.
  EXPECT_EQ(CountDifferent(floor->Render(col0 + 37, row0 + 51, 123, 77), window(cv::Rect(37, 51, 123, 77))), 0);
  EXPECT_EQ(CountDifferent(MakeImageFloor(Patches(scratch / "floor.png"))->Render(col0, row0, 400, 300), window), 0);
  ImageFloorOptions other = Patches(scratch / "floor.png");
  other.seed = 6;
  EXPECT_GT(CountDifferent(MakeImageFloor(other)->Render(col0, row0, 400, 300), window), 400 * 300 / 2);
  EXPECT_NE(floor->Describe().find("layout=patches patch_mm=32 seed=5"), std::string::npos) << floor->Describe();
}

TEST(ImageFloor, PatchesLargerThanThePictureAreRefusedNamingTheFile) {
  const test::ScratchDir scratch;
  ASSERT_TRUE(cv::imwrite((scratch / "small.png").string(), RandomImage(80, 200, CV_8UC1, 7)));
  try {
    MakeImageFloor(Patches(scratch / "small.png"));  // 64 texels and their 16-texel blend
    ADD_FAILURE() << "no error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("small.png"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("patch_mm"), std::string::npos) << e.what();
  }
  ImageFloorOptions options = Patches(scratch / "small.png");
  std::string why;
  options.layout = "mirror";
  EXPECT_FALSE(options.Check(&why));
  EXPECT_NE(why.find("layout 'mirror'"), std::string::npos) << why;
  options.layout = "patches";
  options.patch_mm = 2.0;  // 4 texels
  EXPECT_FALSE(options.Check(&why));
  EXPECT_NE(why.find("at least 8 texels"), std::string::npos) << why;
}

TEST(ImageFloor, RealAsphaltInPatchesDoesNotRepeat) {
  const auto file = test::SharedTexture("asphalt_02_2048.jpg");
  if (!file) GTEST_SKIP() << test::SharedDataMissingMessage();
  ImageFloorOptions options;
  options.image = *file;
  options.layout = "patches";
  const auto floor = MakeImageFloor(options);
  const cv::Mat view = floor->Render(-300, 1900, 640, 480);
  cv::Mat shifted;
  cv::absdiff(floor->Render(2048 - 300, 1900 - 2048, 640, 480), view, shifted);
  EXPECT_GT(cv::mean(shifted)[0], 10.0);
  cv::Scalar mean;
  cv::Scalar stddev;
  cv::meanStdDev(view, mean, stddev);
  EXPECT_GT(stddev[0], 10.0);
}

}  // namespace
}  // namespace mosaicloc::sim
