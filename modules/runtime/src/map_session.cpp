#include "mosaicloc/runtime/map_session.hpp"

#include <cmath>

#include <fmt/format.h>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::runtime {

MapSession::MapSession(const std::filesystem::path& map, const MapSessionOptions& options) {
  std::error_code ec;
  if (options.writable && !std::filesystem::exists(map, ec)) {
    mosaic::MapGrid grid;
    grid.mm_per_px = options.camera_mm_per_px;
    store_ = mosaic::TileStore::Create(map, grid);
    created_ = true;
  } else {
    store_ = mosaic::TileStore::Open(map, options.writable);
  }
  if (std::abs(store_->grid().mm_per_px - options.camera_mm_per_px) > 1e-9) {
    core::ThrowInvalidInput(fmt::format("{}: map resolution {} mm/px differs from the camera's {} mm/px",
                                        map.string(), store_->grid().mm_per_px, options.camera_mm_per_px));
  }
  cache_ = std::make_unique<mosaic::TileCache>(*store_, options.cache_budget_bytes);
  renderer_ = std::make_unique<mosaic::MapRenderer>(*cache_);
  reference_ = std::make_unique<tracking::MapReference>(*renderer_, 0);
  places_ = std::make_unique<tracking::PlaceIndex>(*store_);
  if (options.prefetch) prefetcher_ = std::make_unique<mosaic::TilePrefetcher>(*cache_, *options.prefetch);
}

}  // namespace mosaicloc::runtime
