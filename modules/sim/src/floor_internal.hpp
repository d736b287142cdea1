#pragma once

// Private helpers shared by the floors: integer floor division, the feature hashes and the
// tile cache.

#include <cstddef>
#include <cstdint>
#include <functional>
#include <future>
#include <list>
#include <memory>
#include <mutex>
#include <unordered_map>

#include <opencv2/core/mat.hpp>

/// Before a loop whose iterations are independent (no aliasing between its arrays): lets
/// GCC vectorise it at -O2 without runtime alias checks.
#if defined(__GNUC__) && !defined(__clang__)
#define MOSAICLOC_IVDEP _Pragma("GCC ivdep")
#else
#define MOSAICLOC_IVDEP
#endif

namespace mosaicloc::sim::internal {

/// floor(a / b) and the matching non-negative a mod b, for b > 0.
inline std::int64_t FloorDiv(std::int64_t a, std::int64_t b) {
  const std::int64_t q = a / b;
  return (a % b != 0 && a < 0) ? q - 1 : q;
}
inline std::int64_t FloorMod(std::int64_t a, std::int64_t b) { return a - FloorDiv(a, b) * b; }

/// SplitMix64 finaliser (Steele, Lea, Flood 2014): a bijection with full avalanche.
inline std::uint64_t Mix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

/// "lowbias32" integer hash (C. Wellons, hash-prospector): cheap enough for one call per texel.
inline std::uint32_t Mix32(std::uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352dU;
  x ^= x >> 15;
  x *= 0x846ca68bU;
  x ^= x >> 16;
  return x;
}

/// Key of one feature layer of one floor.
inline std::uint64_t LayerKey(std::uint64_t seed, std::uint64_t layer) {
  return Mix64(Mix64(seed) ^ (layer * 0xd6e8feb86659fd93ULL));
}

/// Key of one world cell of a layer.
inline std::uint64_t CellKey(std::uint64_t layer_key, std::int64_t cell_x, std::int64_t cell_y) {
  return Mix64(Mix64(layer_key ^ static_cast<std::uint64_t>(cell_x)) ^
               (static_cast<std::uint64_t>(cell_y) * 0x9e3779b97f4a7c15ULL));
}

/// A deterministic stream of random numbers started from a cell key.
class CellRandom {
 public:
  explicit CellRandom(std::uint64_t key) : state_(key) {}
  std::uint64_t Next() {
    state_ += 0x9e3779b97f4a7c15ULL;
    return Mix64(state_);
  }
  /// Uniform in [0, 1).
  double Uniform() { return static_cast<double>(Next() >> 11) * 0x1.0p-53; }
  double Uniform(double lo, double hi) { return lo + (hi - lo) * Uniform(); }
  /// Log-uniform in [lo, hi], lo > 0.
  double LogUniform(double lo, double hi);
  /// Standard normal (Box-Muller).
  double Normal();
  /// Poisson with the given mean (inversion; the means used here are small).
  int Poisson(double mean);

 private:
  std::uint64_t state_;
};

/// A thread-safe least-recently-used cache of square CV_8UC1 tiles, bounded in bytes.
/// A missing tile is generated outside the lock; threads that ask for a tile being
/// generated wait for it instead of generating it again.
class TileCache {
 public:
  using Tile = std::shared_ptr<const cv::Mat>;
  using Generator = std::function<cv::Mat(std::int64_t tile_col, std::int64_t tile_row)>;

  TileCache(std::size_t budget_bytes, std::size_t tile_bytes, Generator generate);

  /// The tile; rethrows whatever the generator threw (and forgets the failed tile).
  Tile Get(std::int64_t tile_col, std::int64_t tile_row) const;

 private:
  struct Key {
    std::int64_t col;
    std::int64_t row;
    bool operator==(const Key&) const = default;
  };
  struct KeyHash {
    std::size_t operator()(const Key& key) const {
      return static_cast<std::size_t>(CellKey(0, key.col, key.row));
    }
  };
  struct Entry {
    Key key;
    std::shared_future<Tile> tile;
  };

  std::size_t budget_bytes_;
  std::size_t tile_bytes_;
  Generator generate_;
  mutable std::mutex mutex_;
  mutable std::list<Entry> lru_;  // most recent first
  mutable std::unordered_map<Key, std::list<Entry>::iterator, KeyHash> index_;
};

/// Copies texels [col0, col0 + cols) x [row0, row0 + rows) out of the cache's tiles of
/// tile_size x tile_size texels (tile (i, j) holds texels from (i * tile_size, j * tile_size)).
cv::Mat AssembleFromTiles(const TileCache& cache, int tile_size, std::int64_t col0,
                          std::int64_t row0, int cols, int rows);

/// Throws std::invalid_argument for a negative window size.
void CheckWindowSize(int cols, int rows);

}  // namespace mosaicloc::sim::internal
