#include "mosaicloc/mosaic/renderer.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "warp.hpp"

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

  // The view's samples lie in the parallelogram of its corner pixels' centres (region
  // pixels); pair row r serves the samples with r <= y < r + 1.
  const Eigen::Vector2d origin(static_cast<double>(col0), static_cast<double>(row0));
  const std::array<Eigen::Vector2d, 4> corners = {
      linear * Eigen::Vector2d(0.0, 0.0) + offset - origin, linear * Eigen::Vector2d(width_px - 1.0, 0.0) + offset - origin,
      linear * Eigen::Vector2d(width_px - 1.0, height_px - 1.0) + offset - origin,
      linear * Eigen::Vector2d(0.0, height_px - 1.0) + offset - origin};
  // Each edge as x = x_at_low + (y - y_low) slope between y_low and y_high; its crossing of
  // a band limit needs no division.
  struct Edge {
    double y_low, y_high, x_at_low, slope;
  };
  std::array<Edge, 4> edges;
  for (std::size_t i = 0; i < 4; ++i) {
    Eigen::Vector2d a = corners[i], b = corners[(i + 1) % 4];
    if (a.y() > b.y()) std::swap(a, b);
    edges[i] = {a.y(), b.y(), a.x(), b.y() > a.y() ? (b.x() - a.x()) / (b.y() - a.y()) : 0.0};
  }
  const auto span = [&](int r) {
    // x extent of the parallelogram within the band [r - e, r + 1 + e]: its vertices in the
    // band and its edges' crossings of the band's limits. e covers rounding to 1/32 px.
    constexpr double kMargin = 0.1;
    const double band_low = r - kMargin, band_high = r + 1.0 + kMargin;
    double low = 1e300, high = -1e300;
    for (const Edge& edge : edges) {
      // The edge's part inside the band, clipped; x is linear along it.
      const double y_from = std::max(edge.y_low, band_low), y_to = std::min(edge.y_high, band_high);
      if (y_from > y_to) continue;
      const double x_from = edge.x_at_low + (y_from - edge.y_low) * edge.slope;
      const double x_to = edge.x_at_low + (y_to - edge.y_low) * edge.slope;
      low = std::min(low, std::min(x_from, x_to));
      high = std::max(high, std::max(x_from, x_to));
    }
    if (low > high) return std::pair<int, int>(0, 0);
    // Samples at x read pair columns floor(x) and floor(x) + 1.
    const int begin = std::max(0, static_cast<int>(std::floor(low - kMargin)) - 1);
    const int end = std::min(cols, static_cast<int>(std::floor(high + kMargin)) + 3);
    return std::pair<int, int>(begin, std::max(begin, end));
  };

  // Lay the pairs out straight from the tiles, loading only the tiles a span touches.
  RenderedView view;
  const int t = g.tile_size_px;
  const std::int64_t tc0 = FloorDiv(col0, t), tr0 = FloorDiv(row0, t);
  const int tile_cols = static_cast<int>(FloorDiv(col0 + cols - 1, t) - tc0) + 1;
  const int tile_rows = static_cast<int>(FloorDiv(row0 + rows - 1, t) - tr0) + 1;
  std::vector<std::shared_ptr<const Tile>> tiles(static_cast<std::size_t>(tile_cols * tile_rows));
  bool all_mapped = true;
  const auto tile_at = [&](std::int64_t tc, std::int64_t tr) -> const Tile& {
    std::shared_ptr<const Tile>& slot = tiles[static_cast<std::size_t>((tr - tr0) * tile_cols + (tc - tc0))];
    if (!slot) {
      const TileKey key{level, tc, tr};
      slot = cache_.Peek(key);
      if (!slot) {
        slot = cache_.Get(key);
        ++view.tiles_loaded;
      }
      if (slot->status == TileStatus::kCorrupt) view.problems.push_back(slot->problem);
      all_mapped = all_mapped && slot->status == TileStatus::kOk && slot->fully_mapped;
    }
    return *slot;
  };
  // Per-thread buffers, kept between renders (and not cleared: only the spans are read).
  thread_local std::unique_ptr<std::uint8_t[]> pairs;
  thread_local std::size_t pairs_capacity = 0;
  thread_local std::vector<std::uint8_t> zeros;
  const std::size_t stride = 2 * static_cast<std::size_t>(cols);
  const std::size_t pairs_bytes = stride * static_cast<std::size_t>(rows - 1);
  if (pairs_capacity < pairs_bytes) {
    pairs.reset(new std::uint8_t[pairs_bytes]);
    pairs_capacity = pairs_bytes;
  }
  if (zeros.size() < static_cast<std::size_t>(t)) zeros.assign(static_cast<std::size_t>(t), 0);
  constexpr int kPrefetchRows = 8;
  for (int r = 0; r + 1 < rows; ++r) {
    const auto [begin, end] = span(r);
    const std::int64_t top_row = row0 + r, bottom_row = top_row + 1;
    const std::int64_t top_tile = FloorDiv(top_row, t), bottom_tile = FloorDiv(bottom_row, t);
    for (int c = begin; c < end;) {
      const std::int64_t col = col0 + c;
      const std::int64_t tc = FloorDiv(col, t);
      const int count = static_cast<int>(std::min<std::int64_t>(end - c, (tc + 1) * t - col));
      const auto row_of = [&](std::int64_t tile_row, std::int64_t level_row) -> const std::uint8_t* {
        const Tile& tile = tile_at(tc, tile_row);
        if (tile.status != TileStatus::kOk) return zeros.data();
        return tile.pixels.ptr<std::uint8_t>(static_cast<int>(level_row - tile_row * t)) + (col - tc * t);
      };
      const std::uint8_t* bottom = row_of(bottom_tile, bottom_row);
      // The tile row a few pair rows on, so it is in the cache when this loop gets there.
      const std::int64_t ahead = bottom_row + kPrefetchRows;
      if (ahead < (bottom_tile + 1) * t && bottom != zeros.data()) {
        const std::uint8_t* later = bottom + kPrefetchRows * t;
        for (int k = 0; k < count; k += 64) __builtin_prefetch(later + k);
        __builtin_prefetch(later + count - 1);
      }
      internal::InterleaveRows(row_of(top_tile, top_row), bottom, count,
                               pairs.get() + static_cast<std::size_t>(r) * stride + 2 * static_cast<std::size_t>(c));
      c += count;
    }
  }
  const internal::PairRaster raster{pairs.get(), static_cast<std::ptrdiff_t>(stride), cols, rows};

  const double map[6] = {linear(0, 0), linear(0, 1), offset.x() - static_cast<double>(col0),
                         linear(1, 0), linear(1, 1), offset.y() - static_cast<double>(row0)};
  const cv::Size size(width_px, height_px);
  view.image.create(size, CV_8UC1);
  const int valid = internal::WarpAffineBilinear(raster, map, view.image, all_mapped ? nullptr : &view.mask, all_mapped);
  if (all_mapped) view.mask = cv::Mat(size, CV_8UC1, cv::Scalar(255));
  view.mapped_fraction = static_cast<double>(valid) / static_cast<double>(view.image.total());
  return view;
}

}  // namespace mosaicloc::mosaic
