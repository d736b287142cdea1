#include "mosaicloc/mosaic/renderer.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>

#include <opencv2/core.hpp>

namespace mosaicloc::mosaic {

namespace {

// True when no pixel of the block is kUnmapped; memchr stops at the first.
bool NoneUnmapped(const cv::Mat& block) {
  for (int y = 0; y < block.rows; ++y) {
    if (std::memchr(block.ptr<std::uint8_t>(y), kUnmapped, static_cast<std::size_t>(block.cols)) != nullptr) {
      return false;
    }
  }
  return true;
}

}  // namespace

RasterPatch MapRenderer::Region(int level, std::int64_t col0, std::int64_t row0, int cols, int rows) const {
  RasterPatch patch;
  cv::Mat store;  // the patch's own pixels
  Region(level, col0, row0, cols, rows, store, &patch);
  if (patch.all_mapped) patch.mask = cv::Mat(rows, cols, CV_8UC1, cv::Scalar(255));
  return patch;
}

void MapRenderer::Region(int level, std::int64_t col0, std::int64_t row0, int cols, int rows, cv::Mat& store,
                         RasterPatch* patch) const {
  if (store.type() != CV_8UC1 || store.cols < cols || store.rows < rows) {
    store.create(std::max(store.type() == CV_8UC1 ? store.rows : 0, rows),
                 std::max(store.type() == CV_8UC1 ? store.cols : 0, cols), CV_8UC1);
  }
  patch->image = store(cv::Rect(0, 0, cols, rows));  // every pixel is written below
  patch->level = level;
  patch->col0 = col0;
  patch->row0 = row0;
  patch->tiles_loaded = 0;
  patch->problems.clear();
  bool all_full = true;
  const std::int64_t t = grid().tile_size_px;
  for (std::int64_t tr = FloorDiv(row0, t); tr <= FloorDiv(row0 + rows - 1, t); ++tr) {
    for (std::int64_t tc = FloorDiv(col0, t); tc <= FloorDiv(col0 + cols - 1, t); ++tc) {
      const TileKey key{level, tc, tr};
      std::shared_ptr<const Tile> tile = cache_.Peek(key);
      if (!tile) {
        tile = cache_.Get(key);
        ++patch->tiles_loaded;
      }
      // Overlap of the tile with the region, in level pixels.
      const std::int64_t x0 = std::max(col0, tc * t);
      const std::int64_t y0 = std::max(row0, tr * t);
      const std::int64_t x1 = std::min(col0 + cols, (tc + 1) * t);
      const std::int64_t y1 = std::min(row0 + rows, (tr + 1) * t);
      const cv::Rect from(static_cast<int>(x0 - tc * t), static_cast<int>(y0 - tr * t), static_cast<int>(x1 - x0),
                          static_cast<int>(y1 - y0));
      const cv::Rect to(static_cast<int>(x0 - col0), static_cast<int>(y0 - row0), from.width, from.height);
      if (tile->status == TileStatus::kCorrupt) patch->problems.push_back(tile->problem);
      if (tile->status != TileStatus::kOk) {
        all_full = false;
        patch->image(to).setTo(cv::Scalar(kUnmapped));
        continue;
      }
      // A tile is flagged fully mapped as a whole; the block may lie in the mapped part of one
      // that is not.
      all_full = all_full && (tile->fully_mapped || NoneUnmapped(tile->pixels(from)));
      tile->pixels(from).copyTo(patch->image(to));
    }
  }
  patch->all_mapped = all_full;
  if (all_full) {
    patch->mask.release();
  } else {
    cv::compare(patch->image, cv::Scalar(kUnmapped), patch->mask, cv::CMP_NE);
  }
}

RasterPatch MapRenderer::PatchAround(const Eigen::Vector2d& centre_world_mm, int width_px, int height_px,
                                     int level) const {
  const Eigen::Vector2d centre = grid().WorldToRaster(centre_world_mm, level);
  const auto col0 = static_cast<std::int64_t>(std::lround(centre.x() - 0.5 * (width_px - 1)));
  const auto row0 = static_cast<std::int64_t>(std::lround(centre.y() - 0.5 * (height_px - 1)));
  return Region(level, col0, row0, width_px, height_px);
}

}  // namespace mosaicloc::mosaic
