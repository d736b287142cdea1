#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include <utility>

#include "floor_internal.hpp"

namespace mosaicloc::sim::internal {

double CellRandom::LogUniform(double lo, double hi) {
  return lo * std::exp(std::log(hi / lo) * Uniform());
}

double CellRandom::Normal() {
  const double u1 = 1.0 - Uniform();  // (0, 1]
  const double u2 = Uniform();
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
}

int CellRandom::Poisson(double mean) {
  if (mean > 30.0)
    return std::max(0, static_cast<int>(std::lround(mean + std::sqrt(mean) * Normal())));
  const double limit = std::exp(-mean);
  double product = Uniform();
  int count = 0;
  while (product > limit && count < 1000) {
    product *= Uniform();
    ++count;
  }
  return count;
}

TileCache::TileCache(std::size_t budget_bytes, std::size_t tile_bytes, Generator generate)
    : budget_bytes_(budget_bytes), tile_bytes_(tile_bytes), generate_(std::move(generate)) {}

TileCache::Tile TileCache::Get(std::int64_t tile_col, std::int64_t tile_row) const {
  const Key key{tile_col, tile_row};
  std::unique_lock lock(mutex_);
  if (const auto found = index_.find(key); found != index_.end()) {
    lru_.splice(lru_.begin(), lru_, found->second);
    const std::shared_future<Tile> tile = found->second->tile;
    lock.unlock();
    return tile.get();
  }

  std::promise<Tile> promise;
  const std::shared_future<Tile> future = promise.get_future().share();
  lru_.push_front(Entry{key, future});
  index_[key] = lru_.begin();
  // Evicting a tile still being generated is harmless: its waiters hold the future.
  while (lru_.size() * tile_bytes_ > budget_bytes_ && lru_.size() > 1) {
    index_.erase(lru_.back().key);
    lru_.pop_back();
  }
  lock.unlock();

  try {
    Tile tile = std::make_shared<const cv::Mat>(generate_(tile_col, tile_row));
    promise.set_value(tile);
    return tile;
  } catch (...) {
    promise.set_exception(std::current_exception());
    lock.lock();
    if (const auto found = index_.find(key); found != index_.end()) {
      lru_.erase(found->second);
      index_.erase(found);
    }
    throw;
  }
}

void CheckWindowSize(int cols, int rows) {
  if (cols < 0 || rows < 0) {
    throw std::invalid_argument("Floor::Render: negative window size " + std::to_string(cols) +
                                " x " + std::to_string(rows));
  }
}

cv::Mat AssembleFromTiles(const TileCache& cache, int tile_size, std::int64_t col0,
                          std::int64_t row0, int cols, int rows) {
  CheckWindowSize(cols, rows);
  cv::Mat out(rows, cols, CV_8UC1);
  if (cols == 0 || rows == 0) return out;
  const std::int64_t col_end = col0 + cols;
  const std::int64_t row_end = row0 + rows;
  for (std::int64_t tile_row = FloorDiv(row0, tile_size); tile_row * tile_size < row_end;
       ++tile_row) {
    const std::int64_t tile_top = tile_row * tile_size;
    const std::int64_t top = std::max(row0, tile_top);
    const std::int64_t bottom = std::min(row_end, tile_top + tile_size);
    for (std::int64_t tile_col = FloorDiv(col0, tile_size); tile_col * tile_size < col_end;
         ++tile_col) {
      const std::int64_t tile_left = tile_col * tile_size;
      const std::int64_t left = std::max(col0, tile_left);
      const std::int64_t right = std::min(col_end, tile_left + tile_size);
      const TileCache::Tile tile = cache.Get(tile_col, tile_row);
      const cv::Rect from(static_cast<int>(left - tile_left), static_cast<int>(top - tile_top),
                          static_cast<int>(right - left), static_cast<int>(bottom - top));
      const cv::Rect to(static_cast<int>(left - col0), static_cast<int>(top - row0), from.width,
                        from.height);
      (*tile)(from).copyTo(out(to));
    }
  }
  return out;
}

}  // namespace mosaicloc::sim::internal
