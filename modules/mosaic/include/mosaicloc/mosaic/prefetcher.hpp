#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <optional>
#include <thread>

#include <Eigen/Core>

#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/mosaic/tile_cache.hpp"

namespace mosaicloc::mosaic {

struct PrefetchOptions {
  int level = 0;                 ///< pyramid level the tracker renders from
  double view_radius_mm = 110.0; ///< radius of a circle around the camera footprint (half diagonal + margin)
  double horizon_s = 1.0;        ///< how far ahead along the predicted path
  double step_mm = 40.0;         ///< spacing of the predicted positions
  bool Check(std::string* why) const;
};

/// Loads, on a low-priority thread of its own, the tiles the camera will need next: the
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
  /// rate (rad/s). Returns at once; an older prediction not yet worked on is dropped.
  void Predict(const core::Pose2& world_from_camera, const Eigen::Vector2d& velocity_world_mm_per_s,
               double yaw_rate_radps);
  /// Blocks until the latest prediction has been worked through (for tests and benchmarks).
  void WaitIdle();
  std::int64_t tiles_requested() const { return tiles_requested_.load(); }

 private:
  struct Prediction {
    core::Pose2 world_from_camera;
    Eigen::Vector2d velocity_world_mm_per_s;
    double yaw_rate_radps;
  };
  void Run();
  void Prefetch(const Prediction& prediction);

  TileCache& cache_;
  PrefetchOptions options_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable idle_;
  std::optional<Prediction> pending_;
  bool busy_ = false;
  bool stop_ = false;
  std::atomic<std::int64_t> tiles_requested_{0};
  std::thread thread_;
};

}  // namespace mosaicloc::mosaic
