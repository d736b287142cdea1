#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/mosaic/tile_cache.hpp"

namespace mosaicloc::mosaic {

/// A view rendered from the map.
struct RenderedView {
  cv::Mat image;                ///< CV_8UC1; kUnmapped where the map has no data
  cv::Mat mask;                 ///< CV_8UC1, 255 where every pixel the value came from is mapped
  double mapped_fraction = 0.0;
  int tiles_loaded = 0;         ///< tiles that were not in memory: the render waited for them
  std::vector<std::string> problems;  ///< corrupt tiles met (treated as unmapped)
};

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

/// Renders what an ideal camera would see from the map, seamlessly across tile borders.
/// Const and thread-safe given a thread-safe cache.
class MapRenderer {
 public:
  explicit MapRenderer(TileCache& cache) : cache_(cache) {}

  /// The view of an ideal camera (width x height pixels of mm_per_px, principal point at the
  /// centre, frames of design.md section 3) at world_from_camera, sampled bilinearly from
  /// `level` with the values cv::warpAffine(INTER_LINEAR) gives on the assembled level (its
  /// fixed-point arithmetic, repeated). A pixel is mapped when every level pixel of non-zero
  /// bilinear weight is. Loads only the tiles under the view; keeps a per-thread buffer of
  /// about twice the view's footprint between calls.
  RenderedView RenderView(const core::Pose2& world_from_camera, int width_px, int height_px, double mm_per_px,
                          int level) const;
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
