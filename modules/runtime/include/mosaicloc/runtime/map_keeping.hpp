#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <exception>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include <opencv2/core/mat.hpp>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/core/timestamp.hpp"
#include "mosaicloc/localizer/localizer.hpp"
#include "mosaicloc/localizer/speed_limits.hpp"
#include "mosaicloc/mapping/map_extension.hpp"
#include "mosaicloc/mapping/map_update.hpp"
#include "mosaicloc/runtime/map_session.hpp"
#include "mosaicloc/runtime/settings.hpp"

namespace mosaicloc::runtime {

/// What keeping the map did over a drive.
struct MapKeepingSummary {
  mapping::ExtensionSummary extension;
  mapping::UpdateSummary updates;
  std::int64_t dropped = 0;        ///< frames the background thread could not keep up with (not mapped)
  bool reindexed = false;          ///< the place index and the quality layer were rebuilt at the end
  /// Frames off the map that came more than the overlap speed limit after the one before
  /// (localizer::OverlapSpeedWatch), and the fastest speed off the map, m/s.
  std::int64_t overspeed_frames = 0;
  double mapping_speed_max_mps = 0.0;
  /// Why map keeping stopped before the drive ended (a full disk, the map locked by another
  /// process, ...), or empty. The map holds what was committed before: every write is one
  /// transaction. Localization is not affected.
  std::string failure;
};

/// After a drive whose map keeping stopped early (`failure` not empty): throws core::Error
/// (runtime) saying so for `command`, so that the command, its report already written, ends
/// with an error. Does nothing when `failure` is empty.
void ThrowIfMapKeepingStopped(const std::string& command, const std::string& failure);

/// The map kept up to date as a drive goes (design.md sections 7d and 7e): automatic mapping
/// of the floor off the map (mapping::MapExtender) and automatic map updates of floor that
/// changed (mapping::MapUpdater, when settings.map_update.enabled), fed each frame's outcome.
/// Inline (replay: every frame in order, deterministic) or on a thread of its own (run: the
/// tracking thread hands the outcomes over and never waits for a commit; frames are copied
/// where they are needed, and dropped, counted, if more than `queue_frames` wait).
class MapKeeper {
 public:
  /// `map` must be open for writing and outlive the keeper.
  MapKeeper(MapSession& map, const camera::IdealCamera& camera, const tracking::TrackerOptions& tracker,
            const LocalizationSettings& settings, const core::Pose2& vehicle_from_camera, bool background,
            std::size_t queue_frames = 120);
  ~MapKeeper();
  MapKeeper(const MapKeeper&) = delete;
  MapKeeper& operator=(const MapKeeper&) = delete;

  /// The localizer's outcome of a frame (`image`: the ideal frame it processed). Skipped while
  /// the pose is unknown (`pose_known` false).
  void Frame(core::Timestamp time, const cv::Mat& image, const localizer::FrameOutcome& outcome, bool pose_known);
  /// Processes what waits, commits the open stretch and, when the floor changed, rebuilds the
  /// place index and the quality layer over the whole map (as `map build` makes them).
  /// A write that failed, then or before, stops map keeping and is the summary's `failure`:
  /// it never ends the drive. Call once, after the last Frame.
  MapKeepingSummary Finish();

  /// The camera poses of every frame painted by automatic mapping (after Finish).
  const std::vector<std::pair<core::Timestamp, core::Pose2>>& painted() const { return extender_.painted(); }

 private:
  struct Item {
    mapping::ExtensionFrame extension;
    mapping::UpdateFrame update;
  };
  void Process(const Item& item);
  void Loop();
  // Records why map keeping stops (the first failure) and says so; call with mutex_ held.
  void Stop(const std::exception& error);

  MapSession& map_;
  mapping::MapExtender extender_;
  std::optional<mapping::MapUpdater> updater_;
  core::Pose2 vehicle_from_camera_;
  localizer::OverlapSpeedWatch overspeed_;  // on the calling thread
  bool background_ = false;
  std::size_t queue_frames_ = 120;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<Item> queue_;
  bool finishing_ = false;
  bool finished_ = false;
  std::int64_t dropped_ = 0;
  std::string failure_;
  std::thread thread_;  // last: starts once everything above exists
};

}  // namespace mosaicloc::runtime
