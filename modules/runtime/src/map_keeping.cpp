#include "mosaicloc/runtime/map_keeping.hpp"

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/runtime/map_jobs.hpp"
#include "mosaicloc/runtime/map_quality.hpp"

namespace mosaicloc::runtime {

void ThrowIfMapKeepingStopped(const std::string& command, const std::string& failure) {
  if (failure.empty()) return;
  core::ThrowRuntime(command + ": map keeping stopped (" + failure +
                     "); localization went on to the end, its results are written, and the map holds what was "
                     "committed before");
}

MapKeeper::MapKeeper(MapSession& map, const camera::IdealCamera& camera, const tracking::TrackerOptions& tracker,
                     const LocalizationSettings& settings, const core::Pose2& vehicle_from_camera, bool background,
                     std::size_t queue_frames)
    : map_(map),
      extender_(map.store(), map.cache(), camera, tracker, settings.map_extension),
      vehicle_from_camera_(vehicle_from_camera),
      overspeed_(camera, settings.required_overlap),
      background_(background),
      queue_frames_(queue_frames) {
  if (settings.map_update.enabled) updater_.emplace(map.store(), map.cache(), camera, settings.map_update);
  if (background_) thread_ = std::thread([this] { Loop(); });
}

MapKeeper::~MapKeeper() {
  if (thread_.joinable()) {
    {
      const std::lock_guard lock(mutex_);
      finishing_ = true;
    }
    wake_.notify_all();
    thread_.join();
  }
}

void MapKeeper::Frame(core::Timestamp time, const cv::Mat& image, const localizer::FrameOutcome& outcome,
                      bool pose_known) {
  if (!pose_known) return;
  Item item;
  // The localizer's estimate after the frame (a fix fused, or visual odometry's chain) as the
  // camera's pose.
  const core::Pose2 world_from_camera = outcome.world_from_vehicle * vehicle_from_camera_;
  const bool off_map = outcome.mode == localizer::Mode::kVisualOdometry || outcome.mode == localizer::Mode::kDeadReckoning;
  if (const auto excess = overspeed_.Frame(time, world_from_camera, off_map); excess && excess->first) {
    core::Log().warn(
        "automatic mapping at {:.2f} m/s, above the overlap speed limit of {:.2f} m/s at this frame interval: "
        "consecutive frames share less than {:.0f} % of the view, so the floor off the map may not be chained "
        "and is left unmapped where it breaks; map at a lower speed",
        excess->speed_mps, excess->limit_mps, 100.0 * overspeed_.required_overlap());
  }
  const Eigen::Matrix3d covariance =
      localizer::CameraCovariance(outcome.world_from_vehicle, vehicle_from_camera_, outcome.covariance);
  // Automatic mapping keeps the keyframes' and the fixes' images, and the last frame registered
  // off the map (the next keyframe may be registered against it); map updates look at fixes'.
  const bool needed = outcome.keyframe || outcome.fixed || outcome.link.has_value();
  const cv::Mat kept = !needed ? cv::Mat() : background_ ? image.clone() : image;
  item.extension.time = time;
  item.extension.image = kept;
  item.extension.world_from_camera = world_from_camera;
  item.extension.covariance = covariance;
  item.extension.fixed = outcome.fixed;
  item.extension.keyframe = outcome.keyframe;
  item.extension.link = outcome.link;
  item.update.time = time;
  item.update.image = kept;
  item.update.world_from_camera = world_from_camera;
  item.update.covariance = covariance;
  item.update.fixed = outcome.fixed;
  item.update.restarted = outcome.relocalized;
  item.update.tracking = outcome.lock == estimation::LockState::kTracking && outcome.mode == localizer::Mode::kTrack;
  item.update.nis = outcome.nis;
  if (!background_) {
    if (!failure_.empty()) return;
    try {
      Process(item);
    } catch (const std::exception& error) {
      Stop(error);
    }
    return;
  }
  {
    const std::lock_guard lock(mutex_);
    if (!failure_.empty()) return;
    if (queue_.size() >= queue_frames_) {
      // Behind (a long commit) or stopped: this frame is not mapped. A stretch whose chain
      // breaks here is committed as it stands, and the next one starts from a fix.
      if (++dropped_ == 1) core::Log().warn("map keeping: behind the camera; frames are not mapped until it catches up");
      return;
    }
    queue_.push_back(std::move(item));
  }
  wake_.notify_one();
}

void MapKeeper::Process(const Item& item) {
  extender_.Frame(item.extension);
  if (updater_) updater_->Frame(item.update);
}

void MapKeeper::Loop() {
  while (true) {
    Item item;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [this] { return finishing_ || !queue_.empty(); });
      if (queue_.empty()) return;  // finishing, and nothing left
      item = std::move(queue_.front());
      queue_.pop_front();
    }
    try {
      Process(item);
    } catch (const std::exception& error) {
      const std::lock_guard lock(mutex_);
      Stop(error);
      queue_.clear();
      return;
    }
  }
}

void MapKeeper::Stop(const std::exception& error) {
  if (!failure_.empty()) return;
  failure_ = error.what();
  core::Log().error("map keeping stopped: {}; the map keeps what was committed before and is no longer extended or "
                    "updated on this drive; localization goes on",
                    failure_);
}

MapKeepingSummary MapKeeper::Finish() {
  if (finished_) core::ThrowRuntime("map keeping: Finish called twice");
  finished_ = true;
  if (thread_.joinable()) {
    {
      const std::lock_guard lock(mutex_);
      finishing_ = true;
    }
    wake_.notify_all();
    thread_.join();
  }
  MapKeepingSummary summary;
  if (failure_.empty()) {
    try {
      extender_.Finish();
    } catch (const std::exception& error) {
      Stop(error);
    }
  }
  summary.extension = extender_.summary();
  if (updater_) summary.updates = updater_->summary();
  summary.dropped = dropped_;
  summary.overspeed_frames = overspeed_.frames_over();
  summary.mapping_speed_max_mps = overspeed_.max_speed_mps();
  if (summary.extension.tiles_written > 0 || summary.updates.updates > 0) {
    // The new and the rewritten floor join the place index (global relocalization) and the
    // quality layer, as `map build` makes them.
    try {
      const MapIndexSummary index = IndexStore(map_.store());
      AssessStore(map_.store());
      summary.reindexed = true;
      core::Log().info("map: place index rebuilt ({} features, {:.1f} s), quality layer assessed", index.features,
                       index.seconds);
    } catch (const std::exception& error) {
      Stop(error);
    }
  }
  summary.failure = failure_;
  const mapping::ExtensionSummary& e = summary.extension;
  core::Log().info("map extension: {} stretches ({} closed onto the map), {} frames painted, {} tiles written, {:.1f} s",
                   e.segments, e.closed, e.keyframes, e.tiles_written, e.seconds);
  if (summary.overspeed_frames > 0) {
    core::Log().warn("automatic mapping: {} frames off the map came faster than the overlap speed limit (up to {:.2f} m/s)",
                     summary.overspeed_frames, summary.mapping_speed_max_mps);
  }
  if (updater_) {
    const mapping::UpdateSummary& u = summary.updates;
    core::Log().info("map updates: {} written ({} cells, {} tiles), {} cells seen changed not yet rewritten; {} frames "
                     "compared ({} changed over too much of the view to vote), {} not where the floor repeats; "
                     "{:.1f} s",
                     u.updates, u.cells_updated, u.tiles_written, u.cells_pending, u.compared, u.mostly_changed,
                     u.repeating, u.seconds);
  }
  return summary;
}

}  // namespace mosaicloc::runtime
