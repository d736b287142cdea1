#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "mosaicloc/mosaic/tile_cache.hpp"

namespace mosaicloc::mosaic {

/// An axis-aligned block of a level's pixels.
struct RasterPatch {
  cv::Mat image;  ///< CV_8UC1
  cv::Mat mask;   ///< CV_8UC1, 255 where mapped
  bool all_mapped = false;  ///< every pixel is mapped (then mask is all 255)
  std::int64_t col0 = 0;  ///< level pixel of image (0, 0)
  std::int64_t row0 = 0;
  int level = 0;
  int tiles_loaded = 0;
  std::vector<std::string> problems;
};

/// Reads blocks of a level's pixels from the map, seamlessly across tile borders (the
/// tracker's views are rendered from them: tracking::MapReference, tracking::RenderWindow).
/// Const and thread-safe given a thread-safe cache.
class MapRenderer {
 public:
  explicit MapRenderer(TileCache& cache) : cache_(cache) {}

  /// The pixels [col0, col0 + cols) x [row0, row0 + rows) of a level, as stored.
  RasterPatch Region(int level, std::int64_t col0, std::int64_t row0, int cols, int rows) const;
  /// The same into caller-owned pixels, for readers that fetch blocks every frame:
  /// `patch->image` becomes a cols x rows view of `store`, which grows (and only grows) to hold
  /// it, and `patch->mask` is left empty when every pixel is mapped (`patch->all_mapped`), else
  /// 255 where mapped. The view is overwritten by the next call with the same store.
  void Region(int level, std::int64_t col0, std::int64_t row0, int cols, int rows, cv::Mat& store,
              RasterPatch* patch) const;
  /// The width x height block of `level` pixels centred (to the nearest pixel) on a world point.
  RasterPatch PatchAround(const Eigen::Vector2d& centre_world_mm, int width_px, int height_px, int level) const;

  const MapGrid& grid() const { return cache_.store().grid(); }

 private:
  TileCache& cache_;
};

}  // namespace mosaicloc::mosaic
