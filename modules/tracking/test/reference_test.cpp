#include <algorithm>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/mosaic/tile_cache.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"
#include "mosaicloc/tracking/reference.hpp"
#include "tracking_test_support.hpp"

namespace mosaicloc::tracking {
namespace {

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

}  // namespace
}  // namespace mosaicloc::tracking
