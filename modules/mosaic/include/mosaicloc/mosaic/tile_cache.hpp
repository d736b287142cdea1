#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "mosaicloc/mosaic/grid.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"

namespace mosaicloc::mosaic {

/// A decoded tile as the cache hands it out; immutable once made.
struct Tile {
  TileStatus status = TileStatus::kAbsent;
  cv::Mat pixels;        ///< CV_8UC1 when kOk
  bool fully_mapped = false;  ///< no pixel is kUnmapped
  std::string problem;   ///< when kCorrupt
};

struct TileCacheStats {
  std::int64_t hits = 0;
  std::int64_t misses = 0;
  std::int64_t evictions = 0;
  std::int64_t loads = 0;
  double load_ms_total = 0.0;
  double load_ms_max = 0.0;
  std::size_t bytes = 0;
  std::size_t tiles = 0;
  /// The pixel slabs held (in use or free for reuse): what the decoded tiles really take.
  std::size_t pool_bytes = 0;
};

/// Decoded tiles in an LRU bounded by a byte budget. Safe for concurrent readers and one
/// writer (Invalidate after a store update). Loading happens outside the cache lock, so a
/// slow load never blocks hits on other tiles. A corrupt tile is cached as corrupt (with the
/// reason) and never used as pixels.
///
/// Tile pixels live in slabs of 64 tiles and evicted tiles' slots are recycled: with one
/// heap allocation per tile, the compressed blobs and decoder state allocated between them
/// while loading left holes the heap kept (measured: 45 MiB held free beyond a 256 MiB
/// budget). A tile's pixels are valid while the Tile is held; keep the shared_ptr, not a
/// copy of the Mat header. A tile without pixels (absent: floor never mapped; corrupt) holds
/// no slot: it costs the budget next to nothing, so a drive past unmapped floor caches many.
class TileCache {
 public:
  TileCache(const TileStore& store, std::size_t budget_bytes = std::size_t{256} << 20);

  /// The tile, loading it from the store on a miss.
  std::shared_ptr<const Tile> Get(const TileKey& key);
  /// The tile if it is in memory now; nothing (and no load) otherwise.
  std::shared_ptr<const Tile> Peek(const TileKey& key);
  bool Contains(const TileKey& key);
  /// Drops a tile so the next Get reads the store again.
  void Invalidate(const TileKey& key);
  /// Drops a level-0 tile and every pyramid tile above it (after WriteWithPyramid).
  void InvalidateWithPyramid(const TileKey& level0);
  void Clear();

  TileCacheStats stats() const;
  std::size_t budget_bytes() const { return budget_bytes_; }
  const TileStore& store() const { return store_; }

 private:
  struct Entry {
    std::shared_ptr<const Tile> tile;
    std::size_t bytes;
    std::list<TileKey>::iterator lru;
  };
  static std::size_t Bytes(const Tile& tile);
  void EvictLocked();

  /// Tile-sized slots carved from slabs. Shared with the tiles' deleters, so a tile that
  /// outlives the cache keeps its slab alive.
  struct BufferPool {
    cv::Mat Take(int tile_size_px);
    void Give(cv::Mat slot);
    std::mutex mutex;
    std::vector<cv::Mat> slabs;
    std::vector<cv::Mat> free;
  };
  std::shared_ptr<const Tile> MakeTile(const TileKey& key);

  const TileStore& store_;
  std::size_t budget_bytes_;
  std::shared_ptr<BufferPool> pool_ = std::make_shared<BufferPool>();
  mutable std::mutex mutex_;
  std::list<TileKey> lru_;  ///< most recent first
  std::unordered_map<TileKey, Entry, TileKeyHash> entries_;
  TileCacheStats stats_;
};

}  // namespace mosaicloc::mosaic
