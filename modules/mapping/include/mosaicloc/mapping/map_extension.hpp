#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/core/timestamp.hpp"
#include "mosaicloc/mapping/pose_graph.hpp"
#include "mosaicloc/mosaic/builder.hpp"
#include "mosaicloc/mosaic/tile_cache.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"
#include "mosaicloc/tracking/tracker.hpp"

namespace mosaicloc::mapping {

/// Automatic mapping (design.md section 7d): the floor a vehicle drives over off the map is
/// added to it as it goes.
struct MapExtensionOptions {
  /// A stretch off the map is committed (painted, in one transaction) at the latest after this
  /// much path, held at its start only; the vehicle then tracks what it painted. Shorter: less
  /// lost to a crash, more of a long loop's error left at the far end.
  double max_segment_m = 5.0;
  /// A stretch starts only from a keyframe whose position is known to this, one standard
  /// deviation: the map is never extended from an unconfident pose. (On a map with no floor
  /// yet, the first stretch defines the map's frame and starts from wherever it is.)
  double max_anchor_sigma_mm = 2.0;
  /// The return onto the map is registered against the stretch's last keyframe around the
  /// fix's motion from it, uncertain by this (one standard deviation).
  double return_prior_sigma_mm = 5.0;
  double return_prior_sigma_deg = 1.0;
  mosaic::Blend blend = mosaic::Blend::kFeather;
  bool Check(std::string* why) const;
};

/// One frame as the localizer left it, in camera poses.
struct ExtensionFrame {
  core::Timestamp time;
  cv::Mat image;  ///< the ideal frame (copied where kept)
  core::Pose2 world_from_camera;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();  ///< of world_from_camera
  bool fixed = false;     ///< an accepted fix on the map
  bool keyframe = false;  ///< the localizer keeps it as its keyframe from now on
  /// Registered off the map against the keyframe (or, where that failed, the frame before).
  std::optional<tracking::FrameLink> link;
};

/// What the extension did so far.
struct ExtensionSummary {
  std::int64_t segments = 0;        ///< stretches committed
  std::int64_t closed = 0;          ///< ... of which ended by a return onto the map (held at both ends)
  std::int64_t keyframes = 0;       ///< frames painted
  std::int64_t tiles_written = 0;   ///< level-0 tiles written (the pyramid above them too)
  std::int64_t unanchored = 0;      ///< frames off the map not mapped: no confident keyframe to start from
  std::int64_t bridged = 0;         ///< breaks of the localizer's chain that the stretch registered across
  double closure_max_mm = 0.0;      ///< the largest correction a return made at a stretch's end
  double seconds = 0.0;             ///< spent committing (optimizing and painting)
  std::vector<std::string> warnings;
};

/// Paints the floor off the map into it, in stretches (design.md section 7d). A stretch starts
/// at the keyframe a frame off the map was first registered against (a fix on the map, or the
/// start); the keyframes after it are its nodes, the localizer's frame-to-keyframe
/// registrations its edges (a keyframe registered to the frame before it brings that frame in as
/// a node, with its own registration to the keyframe before). It ends when the vehicle comes back onto the map (the first fix,
/// registered against the last keyframe, holds the far end: a loop closure), when it has
/// grown to max_segment_m, or when the chain breaks and the frame the localizer starts its
/// next chain from does not register against the stretch's last keyframe either. Then the stretch's pose graph is solved
/// with both ends (or the start) held, and its keyframes painted at the solved poses into the
/// pixels the map does not have yet, in one transaction with the pyramid above them; the
/// mapped floor is never moved or overwritten. The cache is told, so the tracker sees the new
/// floor at once. One thread.
class MapExtender {
 public:
  /// `store` must be writable; `store` and `cache` (over it) must outlive the extender. Throws
  /// core::Error (invalid input) when options fail Check().
  MapExtender(mosaic::TileStore& store, mosaic::TileCache& cache, const camera::IdealCamera& camera,
              const tracking::TrackerOptions& tracker, const MapExtensionOptions& options);

  /// The localizer's outcome of the next frame.
  void Frame(const ExtensionFrame& frame);
  /// Commits the open stretch (held at its start): at the end of a drive.
  void Finish();
  const ExtensionSummary& summary() const { return summary_; }
  /// The camera poses of every frame painted so far, in order (for evaluation).
  const std::vector<std::pair<core::Timestamp, core::Pose2>>& painted() const { return painted_; }

 private:
  struct Node {
    core::Timestamp time;
    cv::Mat image;
    core::Pose2 world_from_camera;
    Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  };
  static Node NodeOf(const ExtensionFrame& frame);
  // The next node of the stretch, joined to the last by the localizer's registration.
  void Append(Node node, const tracking::FrameLink& link);
  // Ends the stretch: `end` (a fix on the map) held with `end_edge` from the last node to it,
  // or the start alone; paints and writes. The stretch is empty after.
  void Commit(const std::optional<Node>& end, const std::optional<PoseGraphEdge>& end_edge);
  // `frame` registered against the stretch's last keyframe around the motion the localizer
  // gives it, uncertain as a return onto the map is: the edge from that keyframe to it, or none.
  std::optional<PoseGraphEdge> RegisterToLast(const ExtensionFrame& frame, EdgeKind kind,
                                              tracking::TrackResult* result) const;
  // Paints the nodes (not the held ends) into the pixels the map lacks; one transaction.
  void Paint(const std::vector<Node>& nodes);

  mosaic::TileStore& store_;
  mosaic::TileCache& cache_;
  camera::IdealCamera camera_;
  tracking::Tracker tracker_;
  MapExtensionOptions options_;
  std::optional<Node> keyframe_;  ///< the localizer's keyframe
  /// The last frame registered against the stretch's last keyframe that did not become one, and
  /// that registration: the next keyframe may be registered against it instead.
  struct HeldFrame {
    Node node;  ///< its image buffer reused frame to frame
    tracking::FrameLink link;
    bool held = false;
  } between_;
  std::vector<Node> segment_;     ///< the start, then the keyframes
  std::vector<PoseGraphEdge> edges_;
  double segment_mm_ = 0.0;
  bool unanchored_warned_ = false;
  bool map_empty_ = false;  ///< no floor in the map yet: the first stretch defines its frame
  ExtensionSummary summary_;
  std::vector<std::pair<core::Timestamp, core::Pose2>> painted_;
};

}  // namespace mosaicloc::mapping
