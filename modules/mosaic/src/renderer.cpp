#include "mosaicloc/mosaic/renderer.hpp"

#include <algorithm>
#include <cmath>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace mosaicloc::mosaic {

RasterPatch MapRenderer::Region(int level, std::int64_t col0, std::int64_t row0, int cols, int rows) const {
  RasterPatch patch;
  patch.level = level;
  patch.col0 = col0;
  patch.row0 = row0;
  patch.image.create(rows, cols, CV_8UC1);  // every pixel is written below
  bool all_full = true;
  const std::int64_t t = grid().tile_size_px;
  for (std::int64_t tr = FloorDiv(row0, t); tr <= FloorDiv(row0 + rows - 1, t); ++tr) {
    for (std::int64_t tc = FloorDiv(col0, t); tc <= FloorDiv(col0 + cols - 1, t); ++tc) {
      const TileKey key{level, tc, tr};
      std::shared_ptr<const Tile> tile = cache_.Peek(key);
      if (!tile) {
        tile = cache_.Get(key);
        ++patch.tiles_loaded;
      }
      // Overlap of the tile with the region, in level pixels.
      const std::int64_t x0 = std::max(col0, tc * t);
      const std::int64_t y0 = std::max(row0, tr * t);
      const std::int64_t x1 = std::min(col0 + cols, (tc + 1) * t);
      const std::int64_t y1 = std::min(row0 + rows, (tr + 1) * t);
      const cv::Rect from(static_cast<int>(x0 - tc * t), static_cast<int>(y0 - tr * t), static_cast<int>(x1 - x0),
                          static_cast<int>(y1 - y0));
      const cv::Rect to(static_cast<int>(x0 - col0), static_cast<int>(y0 - row0), from.width, from.height);
      if (tile->status == TileStatus::kCorrupt) patch.problems.push_back(tile->problem);
      if (tile->status != TileStatus::kOk) {
        all_full = false;
        patch.image(to).setTo(cv::Scalar(kUnmapped));
        continue;
      }
      all_full = all_full && tile->fully_mapped;
      tile->pixels(from).copyTo(patch.image(to));
    }
  }
  patch.all_mapped = all_full;
  patch.mask = all_full ? cv::Mat(rows, cols, CV_8UC1, cv::Scalar(255)) : (patch.image != kUnmapped);
  return patch;
}

RasterPatch MapRenderer::PatchAround(const Eigen::Vector2d& centre_world_mm, int width_px, int height_px,
                                     int level) const {
  const Eigen::Vector2d centre = grid().WorldToRaster(centre_world_mm, level);
  const auto col0 = static_cast<std::int64_t>(std::lround(centre.x() - 0.5 * (width_px - 1)));
  const auto row0 = static_cast<std::int64_t>(std::lround(centre.y() - 0.5 * (height_px - 1)));
  return Region(level, col0, row0, width_px, height_px);
}

RenderedView MapRenderer::RenderView(const core::Pose2& world_from_camera, int width_px, int height_px,
                                     double mm_per_px, int level) const {
  // View pixel (u, v) -> world: R diag(s, -s) ((u, v) - c) + t  (the ideal camera);
  // world -> level raster: ((x - x0) / res - 0.5, (y0 - y) / res - 0.5).
  const MapGrid& g = grid();
  const double res = g.LevelMmPerPx(level);
  const double cx = 0.5 * (width_px - 1);
  const double cy = 0.5 * (height_px - 1);
  const Eigen::Matrix2d rotation = world_from_camera.Rotation();
  Eigen::Matrix2d linear;  // d(raster)/d(view pixel)
  linear << rotation(0, 0) * mm_per_px / res, -rotation(0, 1) * mm_per_px / res,
            -rotation(1, 0) * mm_per_px / res, rotation(1, 1) * mm_per_px / res;
  const Eigen::Vector2d centre_raster = g.WorldToRaster(world_from_camera.translation_mm(), level);
  const Eigen::Vector2d offset = centre_raster - linear * Eigen::Vector2d(cx, cy);

  double min_u = 1e300, min_v = 1e300, max_u = -1e300, max_v = -1e300;
  for (const double u : {0.0, width_px - 1.0}) {
    for (const double v : {0.0, height_px - 1.0}) {
      const Eigen::Vector2d raster = linear * Eigen::Vector2d(u, v) + offset;
      min_u = std::min(min_u, raster.x());
      max_u = std::max(max_u, raster.x());
      min_v = std::min(min_v, raster.y());
      max_v = std::max(max_v, raster.y());
    }
  }
  const auto col0 = static_cast<std::int64_t>(std::floor(min_u)) - 1;
  const auto row0 = static_cast<std::int64_t>(std::floor(min_v)) - 1;
  const int cols = static_cast<int>(static_cast<std::int64_t>(std::ceil(max_u)) - col0) + 2;
  const int rows = static_cast<int>(static_cast<std::int64_t>(std::ceil(max_v)) - row0) + 2;
  RasterPatch region = Region(level, col0, row0, cols, rows);

  cv::Mat map(2, 3, CV_64F);
  map.at<double>(0, 0) = linear(0, 0);
  map.at<double>(0, 1) = linear(0, 1);
  map.at<double>(0, 2) = offset.x() - static_cast<double>(col0);
  map.at<double>(1, 0) = linear(1, 0);
  map.at<double>(1, 1) = linear(1, 1);
  map.at<double>(1, 2) = offset.y() - static_cast<double>(row0);

  RenderedView view;
  view.tiles_loaded = region.tiles_loaded;
  view.problems = std::move(region.problems);
  const cv::Size size(width_px, height_px);
  cv::warpAffine(region.image, view.image, map, size, cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT,
                 cv::Scalar(kUnmapped));
  if (region.all_mapped) {
    view.mask = cv::Mat(size, CV_8UC1, cv::Scalar(255));
    view.mapped_fraction = 1.0;
    return view;
  }
  // Fixed-point bilinear weights sum exactly to one, so 255 survives only where every
  // contributing source pixel is mapped.
  cv::Mat warped_mask;
  cv::warpAffine(region.mask, warped_mask, map, size, cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT,
                 cv::Scalar(0));
  view.mask = warped_mask == 255;
  view.image.setTo(cv::Scalar(kUnmapped), ~view.mask);
  view.mapped_fraction = static_cast<double>(cv::countNonZero(view.mask)) / static_cast<double>(view.mask.total());
  return view;
}

}  // namespace mosaicloc::mosaic
