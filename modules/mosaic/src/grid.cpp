#include "mosaicloc/mosaic/grid.hpp"

#include <cmath>

namespace mosaicloc::mosaic {

bool MapGrid::Check(std::string* why) const {
  if (!(mm_per_px > 0.0 && mm_per_px < 1000.0)) {
    *why = "mm_per_px must be in (0, 1000)";
    return false;
  }
  if (!std::isfinite(origin_x_mm) || !std::isfinite(origin_y_mm)) {
    *why = "origin_x_mm and origin_y_mm must be finite";
    return false;
  }
  if (tile_size_px < 16 || tile_size_px > 4096 || (tile_size_px & (tile_size_px - 1)) != 0) {
    *why = "tile_size_px must be a power of two in [16, 4096]";
    return false;
  }
  if (levels < 1 || levels > 16) {
    *why = "levels must be in [1, 16]";
    return false;
  }
  return true;
}

double MapGrid::LevelMmPerPx(int level) const { return std::ldexp(mm_per_px, level); }

Eigen::Vector2d MapGrid::WorldToRaster(const Eigen::Vector2d& world_mm, int level) const {
  const double res = LevelMmPerPx(level);
  return {(world_mm.x() - origin_x_mm) / res - 0.5, (origin_y_mm - world_mm.y()) / res - 0.5};
}

Eigen::Vector2d MapGrid::RasterToWorld(const Eigen::Vector2d& raster, int level) const {
  const double res = LevelMmPerPx(level);
  return {origin_x_mm + (raster.x() + 0.5) * res, origin_y_mm - (raster.y() + 0.5) * res};
}

std::string TileKey::ToString() const {
  return "level " + std::to_string(level) + " col " + std::to_string(col) + " row " + std::to_string(row);
}

}  // namespace mosaicloc::mosaic
