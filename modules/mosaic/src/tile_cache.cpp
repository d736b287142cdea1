#include "mosaicloc/mosaic/tile_cache.hpp"

#include <algorithm>
#include <chrono>

#include <opencv2/core.hpp>

namespace mosaicloc::mosaic {

TileCache::TileCache(const TileStore& store, std::size_t budget_bytes) : store_(store), budget_bytes_(budget_bytes) {}

std::size_t TileCache::Bytes(const Tile& tile) {
  constexpr std::size_t kOverhead = 512;  // entry, list node, control block, Mat header
  return kOverhead + tile.pixels.total() * tile.pixels.elemSize() + tile.problem.size();
}

cv::Mat TileCache::BufferPool::Take(int tile_size_px) {
  constexpr int kSlabTiles = 64;
  const std::lock_guard lock(mutex);
  if (free.empty()) {
    cv::Mat slab(kSlabTiles * tile_size_px, tile_size_px, CV_8UC1);
    for (int i = 0; i < kSlabTiles; ++i) free.push_back(slab.rowRange(i * tile_size_px, (i + 1) * tile_size_px));
    slabs.push_back(slab);
  }
  cv::Mat slot = free.back();
  free.pop_back();
  return slot;
}

void TileCache::BufferPool::Give(cv::Mat slot) {
  const std::lock_guard lock(mutex);
  free.push_back(std::move(slot));
}

std::shared_ptr<const Tile> TileCache::Peek(const TileKey& key) {
  const std::lock_guard lock(mutex_);
  const auto it = entries_.find(key);
  if (it == entries_.end()) return nullptr;
  lru_.splice(lru_.begin(), lru_, it->second.lru);
  return it->second.tile;
}

bool TileCache::Contains(const TileKey& key) {
  const std::lock_guard lock(mutex_);
  return entries_.count(key) != 0;
}

std::shared_ptr<const Tile> TileCache::Get(const TileKey& key) {
  {
    const std::lock_guard lock(mutex_);
    const auto it = entries_.find(key);
    if (it != entries_.end()) {
      ++stats_.hits;
      lru_.splice(lru_.begin(), lru_, it->second.lru);
      return it->second.tile;
    }
    ++stats_.misses;
  }
  const auto start = std::chrono::steady_clock::now();
  std::shared_ptr<const Tile> tile = MakeTile(key);
  const double load_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();

  const std::lock_guard lock(mutex_);
  ++stats_.loads;
  stats_.load_ms_total += load_ms;
  stats_.load_ms_max = std::max(stats_.load_ms_max, load_ms);
  const auto it = entries_.find(key);
  if (it != entries_.end()) return it->second.tile;  // another thread loaded it meanwhile
  lru_.push_front(key);
  const std::size_t bytes = Bytes(*tile);
  entries_.emplace(key, Entry{tile, bytes, lru_.begin()});
  stats_.bytes += bytes;
  EvictLocked();
  return tile;
}

std::shared_ptr<const Tile> TileCache::MakeTile(const TileKey& key) {
  // Decode straight into a slot; the tile's deleter gives the slot back.
  cv::Mat slot = pool_->Take(store_.grid().tile_size_px);
  TileRead read = store_.Read(key, slot);
  if (read.status != TileStatus::kOk) {
    // No pixels: the slot goes back at once. Held by a tile the budget counts at a few hundred
    // bytes, every unmapped tile a drive passed would keep 64 KiB of slab alive.
    pool_->Give(slot);
    auto tile = std::make_shared<Tile>();
    tile->status = read.status;
    tile->problem = std::move(read.problem);
    return tile;
  }
  std::weak_ptr<BufferPool> pool = pool_;
  auto* tile = new Tile();
  std::shared_ptr<Tile> shared(tile, [pool, slot](Tile* dying) {
    delete dying;
    if (const auto alive = pool.lock()) alive->Give(slot);
  });
  tile->status = read.status;
  tile->pixels = std::move(read.pixels);
  tile->fully_mapped = cv::countNonZero(tile->pixels) == static_cast<int>(tile->pixels.total());
  return shared;
}

void TileCache::EvictLocked() {
  // Keep at least the tile just added, even if it alone exceeds a tiny budget.
  while (stats_.bytes > budget_bytes_ && lru_.size() > 1) {
    const TileKey victim = lru_.back();
    lru_.pop_back();
    const auto it = entries_.find(victim);
    stats_.bytes -= it->second.bytes;
    entries_.erase(it);
    ++stats_.evictions;
  }
}

void TileCache::Invalidate(const TileKey& key) {
  const std::lock_guard lock(mutex_);
  const auto it = entries_.find(key);
  if (it == entries_.end()) return;
  stats_.bytes -= it->second.bytes;
  lru_.erase(it->second.lru);
  entries_.erase(it);
}

void TileCache::InvalidateWithPyramid(const TileKey& level0) {
  for (int level = 0; level < store_.grid().levels; ++level) {
    const std::int64_t factor = std::int64_t{1} << level;
    Invalidate(TileKey{level, FloorDiv(level0.col, factor), FloorDiv(level0.row, factor)});
  }
}

void TileCache::Clear() {
  const std::lock_guard lock(mutex_);
  entries_.clear();
  lru_.clear();
  stats_.bytes = 0;
}

TileCacheStats TileCache::stats() const {
  const std::lock_guard lock(mutex_);
  TileCacheStats copy = stats_;
  copy.tiles = entries_.size();
  const std::lock_guard pool_lock(pool_->mutex);
  for (const cv::Mat& slab : pool_->slabs) copy.pool_bytes += slab.total() * slab.elemSize();
  return copy;
}

}  // namespace mosaicloc::mosaic
