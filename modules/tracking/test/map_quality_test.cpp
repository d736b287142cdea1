#include "mosaicloc/tracking/map_quality.hpp"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/mosaic/builder.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::tracking {
namespace {

// A lane 1152 mm long and 128 mm wide (y in [-128, 0]) of three floors, 384 mm each: natural
// texture, a 48 mm patch of it repeated, and plain grey with a little noise.
std::unique_ptr<mosaic::TileStore> ThreeFloors(const std::filesystem::path& file) {
  mosaic::MapGrid grid;  // 0.25 mm/px, 256 px tiles
  auto store = mosaic::TileStore::Create(file, grid);
  cv::RNG rng(7);
  cv::Mat noise(512, 4608, CV_32F);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, 1.0);
  cv::GaussianBlur(noise, noise, cv::Size(), 3.0);
  cv::Mat natural;
  cv::normalize(noise, natural, 30, 225, cv::NORM_MINMAX, CV_8U);
  cv::Mat lane(512, 4608, CV_8UC1);
  natural.colRange(0, 1536).copyTo(lane.colRange(0, 1536));
  const cv::Mat patch = natural(cv::Rect(0, 0, 192, 192));  // 48 mm
  for (int y = 0; y < 512; y += 192) {
    for (int x = 1536; x < 3072; x += 192) {
      const cv::Rect r(x, y, std::min(192, 3072 - x), std::min(192, 512 - y));
      patch(cv::Rect(0, 0, r.width, r.height)).copyTo(lane(r));
    }
  }
  cv::Mat plain(512, 1536, CV_8UC1);
  rng.fill(plain, cv::RNG::UNIFORM, 126, 130);
  plain.copyTo(lane.colRange(3072, 4608));
  std::vector<mosaic::TileWrite> tiles;
  for (int row = 0; row < 2; ++row) {
    for (int col = 0; col < 18; ++col) tiles.push_back({{0, col, row}, lane(cv::Rect(col * 256, row * 256, 256, 256)).clone()});
  }
  mosaic::WriteWithPyramid(*store, tiles);
  return store;
}

TEST(MapQuality, TellsNaturalRepeatingAndPlainFloorApart) {
  test::ScratchDir dir;
  const auto store = ThreeFloors(dir / "lane.mosaic");
  MapQualityOptions options;
  options.search_radius_mm = 200.0;
  std::vector<double> fractions;
  const std::vector<mosaic::QualityCell> cells =
      AssessMapQuality(*store, options, [&](double f) { fractions.push_back(f); });
  ASSERT_EQ(cells.size(), 9u);  // 128 mm cells of level 1 along 1152 mm
  ASSERT_FALSE(fractions.empty());
  EXPECT_DOUBLE_EQ(fractions.back(), 1.0);
  const mosaic::QualityThresholds thresholds;
  for (const mosaic::QualityCell& cell : cells) {
    EXPECT_FLOAT_EQ(cell.mapped, 1.0f);
    const std::string why = mosaic::WeakBecause(cell, thresholds);
    // Cells wholly on one floor: natural 0-2, repeating 3-5, plain 6-8 (the neighbours of a
    // border see the next floor within their search).
    if (cell.col <= 1) {
      EXPECT_EQ(why, "") << "natural, col " << cell.col << ": texture " << cell.texture << ", ambiguity " << cell.ambiguity;
      EXPECT_LT(cell.ambiguity, 0.6f);
    } else if (cell.col >= 3 && cell.col <= 5) {
      EXPECT_EQ(why, "repeats") << "col " << cell.col << ": ambiguity " << cell.ambiguity;
      EXPECT_GT(cell.ambiguity, 0.98f);
    } else if (cell.col >= 7) {
      EXPECT_NE(why.find("little texture"), std::string::npos) << "col " << cell.col << ": texture " << cell.texture;
    }
  }
}

TEST(MapQuality, BadOptionsAndLevelsAreRefused) {
  test::ScratchDir dir;
  const auto store = ThreeFloors(dir / "lane.mosaic");
  MapQualityOptions options;
  options.exclusion_mm = 700.0;  // beyond the search radius
  EXPECT_THROW(AssessMapQuality(*store, options), core::Error);
  options = MapQualityOptions{};
  options.search_level = 7;  // the map has 6
  EXPECT_THROW(AssessMapQuality(*store, options), core::Error);
}

}  // namespace
}  // namespace mosaicloc::tracking
