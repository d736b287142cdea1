#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include <Eigen/Core>

namespace mosaicloc::mosaic {

/// Where a map's pixels are (design.md section 3). Level 0 has `mm_per_px` r and origin
/// (x0, y0), the world position of the top-left corner of pixel (0, 0); level k has
/// resolution r 2^k and the same origin. Pixel (col, row) of level k has its centre at
///   x = x0 + (col + 0.5) r 2^k,  y = y0 - (row + 0.5) r 2^k.
/// Continuous raster coordinates put pixel centres at integers (as OpenCV does):
///   u = (x - x0) / (r 2^k) - 0.5,  v = (y0 - y) / (r 2^k) - 0.5.
/// Tiles are tile_size_px squares: tile (col, row) of a level holds its pixels
/// [col T, (col + 1) T) x [row T, (row + 1) T). Tile indices may be negative.
struct MapGrid {
  double mm_per_px = 0.25;
  double origin_x_mm = 0.0;
  double origin_y_mm = 0.0;
  int tile_size_px = 256;
  int levels = 6;

  bool Check(std::string* why) const;
  double LevelMmPerPx(int level) const;
  /// World (mm) to continuous raster coordinates of a level, and back.
  Eigen::Vector2d WorldToRaster(const Eigen::Vector2d& world_mm, int level) const;
  Eigen::Vector2d RasterToWorld(const Eigen::Vector2d& raster, int level) const;
};

/// A tile's address.
struct TileKey {
  int level = 0;
  std::int64_t col = 0;
  std::int64_t row = 0;
  bool operator==(const TileKey&) const = default;
  std::string ToString() const;  ///< "level 0 col 3 row -2", for messages
};

struct TileKeyHash {
  std::size_t operator()(const TileKey& key) const {
    std::uint64_t h = static_cast<std::uint64_t>(key.level) * 0x9e3779b97f4a7c15ULL;
    h ^= static_cast<std::uint64_t>(key.col) * 0xc2b2ae3d27d4eb4fULL + (h << 6) + (h >> 2);
    h ^= static_cast<std::uint64_t>(key.row) * 0x165667b19e3779f9ULL + (h << 6) + (h >> 2);
    return static_cast<std::size_t>(h);
  }
};

/// Integer division rounding towards minus infinity (tile of a negative pixel index).
constexpr std::int64_t FloorDiv(std::int64_t a, std::int64_t b) {
  return a / b - ((a % b != 0) && ((a < 0) != (b < 0)) ? 1 : 0);
}

}  // namespace mosaicloc::mosaic
