#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include <Eigen/Core>

#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/mosaic/tile_cache.hpp"

namespace mosaicloc::mosaic {

struct PrefetchOptions {
  int level = 0;                 ///< pyramid level the tracker renders from
  double view_radius_mm = 110.0; ///< radius of a circle around the camera footprint (half diagonal + margin)
  double horizon_s = 1.0;        ///< how far ahead along the predicted path
  double step_mm = 40.0;         ///< spacing of the predicted positions
  /// Loader threads. A tile read from disk can take hundreds of milliseconds when the disk
  /// is busy; with several loaders that holds up one of them, not the whole horizon, and
  /// the reads the others issue meanwhile overlap on the disk.
  int threads = 3;
  /// The tightest turn the vehicle makes (0: not used). Besides the predicted arc, the
  /// prefetcher then also loads, nearest first, the paths that turn this tightly either way
  /// and the straight path, each as far as `branch_mm`: where the vehicle may go next if
  /// it starts or ends a turn now. A constant-rate prediction sees a turn only once it has
  /// begun, and sees it end only once it has ended.
  double min_turn_radius_mm = 0.0;
  double branch_mm = 600.0;
  bool Check(std::string* why) const;
};

/// Loads, on low-priority threads of its own, the tiles the camera will need next: the
/// footprints along the path predicted from a pose and a constant velocity and yaw rate.
/// The tracking thread then finds them in memory. It only reads through the cache, so the
/// cache's byte budget bounds its memory.
class TilePrefetcher {
 public:
  TilePrefetcher(TileCache& cache, const PrefetchOptions& options);
  ~TilePrefetcher();
  TilePrefetcher(const TilePrefetcher&) = delete;
  TilePrefetcher& operator=(const TilePrefetcher&) = delete;

  /// The latest prediction: camera pose, its velocity in the world frame (mm/s) and yaw
  /// rate (rad/s). Returns at once. The loaders drop what is left of the previous
  /// prediction and start on this one, nearest tiles first.
  void Predict(const core::Pose2& world_from_camera, const Eigen::Vector2d& velocity_world_mm_per_s,
               double yaw_rate_radps);
  /// Blocks until the latest prediction has been worked through (for tests and benchmarks).
  void WaitIdle();
  std::int64_t tiles_requested() const { return tiles_requested_.load(); }

  struct Prediction {
    core::Pose2 world_from_camera;
    Eigen::Vector2d velocity_world_mm_per_s;
    double yaw_rate_radps;
  };
  /// The tiles a prediction asks for, in the order they are loaded (no repeats).
  std::vector<TileKey> Plan(const Prediction& prediction) const;

 private:
  void Run();
  bool IdleLocked() const;

  TileCache& cache_;
  PrefetchOptions options_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable idle_;
  std::optional<Prediction> pending_;
  std::uint64_t pending_sequence_ = 0;  ///< of the latest prediction
  std::uint64_t plan_sequence_ = 0;     ///< of the prediction plan_ was made from
  std::vector<TileKey> plan_;
  std::size_t next_ = 0;  ///< next entry of plan_ to load
  int planning_ = 0;      ///< loaders making a plan
  int loading_ = 0;       ///< loaders reading a tile
  bool stop_ = false;
  std::atomic<std::int64_t> tiles_requested_{0};
  std::vector<std::thread> threads_;
};

}  // namespace mosaicloc::mosaic
