#include "mosaicloc/mosaic/prefetcher.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_set>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::mosaic {

bool PrefetchOptions::Check(std::string* why) const {
  if (level < 0 || !(view_radius_mm > 0.0) || !(horizon_s >= 0.0) || !(step_mm > 0.0)) {
    *why = "prefetch: level >= 0, view_radius_mm > 0, horizon_s >= 0 and step_mm > 0 are required";
    return false;
  }
  if (threads < 1 || threads > 16) {
    *why = "prefetch: threads must be 1-16, not " + std::to_string(threads);
    return false;
  }
  if (!(min_turn_radius_mm >= 0.0) || !(branch_mm >= 0.0)) {
    *why = "prefetch: min_turn_radius_mm and branch_mm must be >= 0";
    return false;
  }
  return true;
}

TilePrefetcher::TilePrefetcher(TileCache& cache, const PrefetchOptions& options) : cache_(cache), options_(options) {
  std::string why;
  if (!options_.Check(&why)) core::ThrowInvalidInput(why);
  for (int i = 0; i < options_.threads; ++i) threads_.emplace_back([this] { Run(); });
}

TilePrefetcher::~TilePrefetcher() {
  {
    const std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  for (auto& thread : threads_) thread.join();
}

void TilePrefetcher::Predict(const core::Pose2& world_from_camera, const Eigen::Vector2d& velocity_world_mm_per_s,
                             double yaw_rate_radps) {
  {
    const std::lock_guard lock(mutex_);
    pending_ = Prediction{world_from_camera, velocity_world_mm_per_s, yaw_rate_radps};
    ++pending_sequence_;
  }
  wake_.notify_one();
}

bool TilePrefetcher::IdleLocked() const { return !pending_ && planning_ == 0 && loading_ == 0 && next_ >= plan_.size(); }

void TilePrefetcher::WaitIdle() {
  std::unique_lock lock(mutex_);
  idle_.wait(lock, [this] { return IdleLocked(); });
}

void TilePrefetcher::Run() {
  // Every loader plans as well as loads: whichever is free when a prediction arrives makes
  // its plan (outside the lock, tens of microseconds) and all of them then work down it.
  std::unique_lock lock(mutex_);
  while (true) {
    wake_.wait(lock, [this] { return stop_ || pending_.has_value() || next_ < plan_.size(); });
    if (stop_) return;
    if (pending_) {
      const Prediction prediction = *pending_;
      const std::uint64_t sequence = pending_sequence_;
      pending_.reset();
      ++planning_;
      lock.unlock();
      std::vector<TileKey> plan = Plan(prediction);
      lock.lock();
      --planning_;
      // Another loader may have planned a newer prediction meanwhile.
      if (sequence > plan_sequence_) {
        plan_ = std::move(plan);
        plan_sequence_ = sequence;
        next_ = 0;
        wake_.notify_all();
      }
    } else {
      const TileKey key = plan_[next_++];
      ++loading_;
      lock.unlock();
      cache_.Get(key);
      ++tiles_requested_;
      lock.lock();
      --loading_;
    }
    if (IdleLocked()) idle_.notify_all();
  }
}

std::vector<TileKey> TilePrefetcher::Plan(const Prediction& prediction) const {
  // Positions along the predicted arc (constant velocity and yaw rate) and, for the first
  // branch_mm, along the branches, all ordered by the distance travelled to reach them;
  // the tiles under a disc of view_radius around each, in that order.
  const MapGrid& grid = cache_.store().grid();
  const double tile_mm = grid.LevelMmPerPx(options_.level) * grid.tile_size_px;
  const double speed = prediction.velocity_world_mm_per_s.norm();
  const double heading = std::atan2(prediction.velocity_world_mm_per_s.y(), prediction.velocity_world_mm_per_s.x());
  const core::Pose2 start(prediction.world_from_camera.translation_mm(), heading);
  const double length_mm = speed > 1e-9 ? std::min(speed * options_.horizon_s, 1e6) : 0.0;
  std::vector<double> curvatures{speed > 1e-9 ? prediction.yaw_rate_radps / speed : 0.0};
  if (options_.min_turn_radius_mm > 0.0) {
    for (const double branch : {0.0, 1.0 / options_.min_turn_radius_mm, -1.0 / options_.min_turn_radius_mm}) {
      if (std::abs(branch - curvatures.front()) > 1e-9) curvatures.push_back(branch);
    }
  }
  const double branch_length_mm = std::min(options_.branch_mm, length_mm);
  const int steps = static_cast<int>(std::ceil(length_mm / options_.step_mm));
  const std::int64_t t_px = grid.tile_size_px;
  std::unordered_set<TileKey, TileKeyHash> seen;
  std::vector<TileKey> plan;
  const auto add_disc = [&](const Eigen::Vector2d& centre) {
    const Eigen::Vector2d low = grid.WorldToRaster(centre + Eigen::Vector2d(-options_.view_radius_mm, options_.view_radius_mm), options_.level);
    const Eigen::Vector2d high = grid.WorldToRaster(centre + Eigen::Vector2d(options_.view_radius_mm, -options_.view_radius_mm), options_.level);
    for (std::int64_t row = FloorDiv(static_cast<std::int64_t>(std::floor(low.y())), t_px);
         row <= FloorDiv(static_cast<std::int64_t>(std::ceil(high.y())), t_px); ++row) {
      for (std::int64_t col = FloorDiv(static_cast<std::int64_t>(std::floor(low.x())), t_px);
           col <= FloorDiv(static_cast<std::int64_t>(std::ceil(high.x())), t_px); ++col) {
        // Skip tiles whose square lies wholly outside the disc.
        const Eigen::Vector2d tile_centre = grid.RasterToWorld(
            {(static_cast<double>(col) + 0.5) * t_px - 0.5, (static_cast<double>(row) + 0.5) * t_px - 0.5}, options_.level);
        const Eigen::Vector2d d = (tile_centre - centre).cwiseAbs() - Eigen::Vector2d::Constant(0.5 * tile_mm);
        if (d.cwiseMax(0.0).norm() > options_.view_radius_mm) continue;
        const TileKey key{options_.level, col, row};
        if (seen.insert(key).second) plan.push_back(key);
      }
    }
  };
  for (int i = 0; i <= steps; ++i) {
    const double s = steps > 0 ? length_mm * i / steps : 0.0;
    for (std::size_t c = 0; c < curvatures.size(); ++c) {
      if (c > 0 && s > branch_length_mm) break;
      add_disc((start * core::Pose2::Exp(Eigen::Vector3d(s, 0.0, curvatures[c] * s))).translation_mm());
    }
  }
  return plan;
}

}  // namespace mosaicloc::mosaic
