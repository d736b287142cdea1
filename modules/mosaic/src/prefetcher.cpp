#include "mosaicloc/mosaic/prefetcher.hpp"

#include <cmath>
#include <unordered_set>
#include <vector>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::mosaic {

bool PrefetchOptions::Check(std::string* why) const {
  if (level < 0 || !(view_radius_mm > 0.0) || !(horizon_s >= 0.0) || !(step_mm > 0.0)) {
    *why = "prefetch: level >= 0, view_radius_mm > 0, horizon_s >= 0 and step_mm > 0 are required";
    return false;
  }
  return true;
}

TilePrefetcher::TilePrefetcher(TileCache& cache, const PrefetchOptions& options) : cache_(cache), options_(options) {
  std::string why;
  if (!options_.Check(&why)) core::ThrowInvalidInput(why);
  thread_ = std::thread([this] { Run(); });
}

TilePrefetcher::~TilePrefetcher() {
  {
    const std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

void TilePrefetcher::Predict(const core::Pose2& world_from_camera, const Eigen::Vector2d& velocity_world_mm_per_s,
                             double yaw_rate_radps) {
  {
    const std::lock_guard lock(mutex_);
    pending_ = Prediction{world_from_camera, velocity_world_mm_per_s, yaw_rate_radps};
  }
  wake_.notify_one();
}

void TilePrefetcher::WaitIdle() {
  std::unique_lock lock(mutex_);
  idle_.wait(lock, [this] { return !pending_ && !busy_; });
}

void TilePrefetcher::Run() {
  std::unique_lock lock(mutex_);
  while (true) {
    wake_.wait(lock, [this] { return stop_ || pending_.has_value(); });
    if (stop_) return;
    const Prediction prediction = *pending_;
    pending_.reset();
    busy_ = true;
    lock.unlock();
    Prefetch(prediction);
    lock.lock();
    busy_ = false;
    if (!pending_) idle_.notify_all();
  }
}

void TilePrefetcher::Prefetch(const Prediction& prediction) {
  // Positions along the predicted arc (constant velocity and yaw rate), nearest first; the
  // tiles under a disc of view_radius around each, in that order.
  const MapGrid& grid = cache_.store().grid();
  const double tile_mm = grid.LevelMmPerPx(options_.level) * grid.tile_size_px;
  const double speed = prediction.velocity_world_mm_per_s.norm();
  const double duration_s = speed > 1e-9 ? std::min(options_.horizon_s, 1e6 / speed) : 0.0;
  const int steps = speed > 1e-9 ? static_cast<int>(std::ceil(speed * duration_s / options_.step_mm)) : 0;
  const double heading = std::atan2(prediction.velocity_world_mm_per_s.y(), prediction.velocity_world_mm_per_s.x());
  std::unordered_set<TileKey, TileKeyHash> seen;
  for (int i = 0; i <= steps; ++i) {
    const double t = steps > 0 ? duration_s * i / steps : 0.0;
    const Eigen::Vector3d twist(speed * t, 0.0, prediction.yaw_rate_radps * t);
    const Eigen::Vector2d centre =
        (core::Pose2(prediction.world_from_camera.translation_mm(), heading) * core::Pose2::Exp(twist)).translation_mm();
    const Eigen::Vector2d low = grid.WorldToRaster(centre + Eigen::Vector2d(-options_.view_radius_mm, options_.view_radius_mm), options_.level);
    const Eigen::Vector2d high = grid.WorldToRaster(centre + Eigen::Vector2d(options_.view_radius_mm, -options_.view_radius_mm), options_.level);
    const std::int64_t t_px = grid.tile_size_px;
    for (std::int64_t row = FloorDiv(static_cast<std::int64_t>(std::floor(low.y())), t_px);
         row <= FloorDiv(static_cast<std::int64_t>(std::ceil(high.y())), t_px); ++row) {
      for (std::int64_t col = FloorDiv(static_cast<std::int64_t>(std::floor(low.x())), t_px);
           col <= FloorDiv(static_cast<std::int64_t>(std::ceil(high.x())), t_px); ++col) {
        const TileKey key{options_.level, col, row};
        if (!seen.insert(key).second) continue;
        // Skip tiles whose square lies wholly outside the disc.
        const Eigen::Vector2d tile_centre = grid.RasterToWorld(
            {(static_cast<double>(col) + 0.5) * t_px - 0.5, (static_cast<double>(row) + 0.5) * t_px - 0.5}, options_.level);
        const Eigen::Vector2d d = (tile_centre - centre).cwiseAbs() - Eigen::Vector2d::Constant(0.5 * tile_mm);
        if (d.cwiseMax(0.0).norm() > options_.view_radius_mm) continue;
        cache_.Get(key);
        ++tiles_requested_;
      }
    }
    {
      // A newer prediction replaces this one at once. Its first positions are the tiles
      // just loaded, found in a few microseconds each, so restarting loses little; working
      // on to the end of a stale horizon does lose: at the start of a turn the straight
      // path's last second of tiles would be loaded before the turn's.
      const std::lock_guard lock(mutex_);
      if (stop_ || pending_) return;
    }
  }
}

}  // namespace mosaicloc::mosaic
