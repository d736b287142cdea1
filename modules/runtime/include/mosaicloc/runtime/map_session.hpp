#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>
#include <optional>

#include "mosaicloc/mosaic/prefetcher.hpp"
#include "mosaicloc/mosaic/renderer.hpp"
#include "mosaicloc/mosaic/tile_cache.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"
#include "mosaicloc/tracking/place_index.hpp"
#include "mosaicloc/tracking/reference.hpp"

namespace mosaicloc::runtime {

struct MapSessionOptions {
  std::size_t cache_budget_bytes = std::size_t{256} << 20;
  /// The map's resolution must be the camera's, mm/px.
  double camera_mm_per_px = 0.25;
  /// Load tiles ahead on threads of their own along predicted paths; none: the tracker loads
  /// what it needs itself.
  std::optional<mosaic::PrefetchOptions> prefetch;
  /// Open for writing (automatic mapping), and create an empty map at the camera's resolution
  /// when the file does not exist.
  bool writable = false;
};

/// An open map, read-only: the tile store, the byte-bounded cache over it, the renderer, the
/// tracker's reference raster (level 0), the place index (loaded on first use) and, when
/// asked for, the prefetcher; opened in this
/// order and closed in the reverse one (the prefetcher stops before the cache goes).
class MapSession {
 public:
  /// Throws core::Error (invalid input) naming the file when it is not a mosaic map or its
  /// resolution is not the camera's.
  MapSession(const std::filesystem::path& map, const MapSessionOptions& options);
  MapSession(const MapSession&) = delete;
  MapSession& operator=(const MapSession&) = delete;

  const tracking::MapReference& reference() const { return *reference_; }
  /// The map's place index for global relocalization; places().problem() says why it cannot
  /// be used (an older map without one).
  const tracking::PlaceIndex& places() const { return *places_; }
  const mosaic::TileCache& cache() const { return *cache_; }
  mosaic::TileCache& cache() { return *cache_; }
  /// What the map's decoded tiles take, MiB: the cache's slabs (reused, never freed).
  double cache_mib() const { return static_cast<double>(cache_->stats().pool_bytes) / (1 << 20); }
  const mosaic::MapGrid& grid() const { return store_->grid(); }
  mosaic::TileStore& store() { return *store_; }
  /// The map file was created empty by this session (MapSessionOptions::writable).
  bool created() const { return created_; }
  const mosaic::MapRenderer& renderer() const { return *renderer_; }
  /// Null without prefetching.
  mosaic::TilePrefetcher* prefetcher() { return prefetcher_.get(); }

 private:
  bool created_ = false;
  std::unique_ptr<mosaic::TileStore> store_;
  std::unique_ptr<mosaic::TileCache> cache_;
  std::unique_ptr<mosaic::MapRenderer> renderer_;
  std::unique_ptr<tracking::MapReference> reference_;
  std::unique_ptr<tracking::PlaceIndex> places_;
  std::unique_ptr<mosaic::TilePrefetcher> prefetcher_;  // last: stops first
};

}  // namespace mosaicloc::runtime
