#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"

namespace mosaicloc::tracking {

/// The place index's record format (design.md section 4); a map whose index has another
/// version or method is treated as having none, with a message to rebuild it.
inline constexpr int kPlaceIndexFormatVersion = 1;
inline constexpr const char* kPlaceIndexMethod = "orb256";
/// Bytes of one feature's record in a cell: x_mm, y_mm and the corner's orientation in the
/// world (float32 each), then its 256-bit descriptor.
inline constexpr std::size_t kPlaceRecordBytes = 3 * sizeof(float) + 32;

/// How the place index describes the map and how a frame is looked up in it (design.md
/// section 7b). Oriented FAST corners with rotated BRIEF descriptors (OpenCV's ORB) at one
/// scale, the map's level `level`; the frame is brought to that resolution first. A frame's
/// corners are matched to the map's (approximate nearest neighbours in Hamming distance,
/// locality-sensitive hashing by bit sampling), each match votes for a camera pose (x, y, yaw), and the best-voted poses are
/// fitted to their matches (RANSAC, then least squares) to give the candidates.
struct PlaceIndexOptions {
  int level = 1;                 ///< map level of the features (1: 2x the camera's mm/px)
  int features_per_tile = 300;   ///< at most, spread over the tile's 4 x 4 blocks
  int frame_features = 600;      ///< at most, in a frame
  int fast_threshold = 8;        ///< FAST's intensity threshold (grey levels)
  int neighbours = 3;            ///< map features per frame feature: a repeating floor has copies
  /// Locality-sensitive hashing by bit sampling: tables, and descriptor bits per key. Keys of
  /// 16 bits made buckets of hundreds on an 85 m map (290 ms a frame), 24 bits a few (13 ms).
  int lsh_tables = 12;
  int lsh_key_bits = 24;
  int max_hamming = 64;          ///< of 256 bits, for a match
  double bin_mm = 16.0;          ///< vote bins: position
  double bin_deg = 12.0;         ///< and yaw
  double inlier_mm = 1.5;        ///< of a fitted pose, at the feature
  int min_inliers = 8;           ///< for a candidate
  int max_candidates = 6;        ///< best fitted poses returned
  bool Check(std::string* why) const;
};

/// A pose the index proposes for a frame, to be verified by the tracker.
struct PlaceCandidate {
  core::Pose2 world_from_camera;
  int inliers = 0;            ///< matches agreeing with the pose
  double rms_mm = 0.0;        ///< their residual
};

/// What a look-up found, with its cost.
struct PlaceLookup {
  std::vector<PlaceCandidate> candidates;  ///< most inliers first
  int frame_features = 0;
  int matches = 0;
  std::string problem;  ///< why there are none, when the index cannot be used
};

/// Records over every tile of the index's level of a map: the cells the map file stores.
/// `progress` gets the share done. Throws core::Error (invalid input) on bad options.
std::vector<mosaic::PlaceCell> BuildPlaceCells(const mosaic::TileStore& store, const PlaceIndexOptions& options,
                                               const std::function<void(double)>& progress = {});
/// The metadata the store keeps with cells built with `options`.
mosaic::PlaceIndexInfo PlaceIndexInfoFor(const PlaceIndexOptions& options);

/// The place index of an open map. Constructed cheaply (reads the index's metadata only);
/// the records are read and the search structure built on first use, under a lock, so that
/// a map that is never searched globally costs nothing. Thread-safe.
class PlaceIndex {
 public:
  /// `store` must outlive the index.
  PlaceIndex(const mosaic::TileStore& store, const PlaceIndexOptions& options = {});
  ~PlaceIndex();
  PlaceIndex(const PlaceIndex&) = delete;
  PlaceIndex& operator=(const PlaceIndex&) = delete;

  /// Empty when the map has a usable index, else why not (no index, an old format, damaged).
  /// A damaged cell is found only when the index is loaded.
  std::string problem() const;
  bool usable() const { return problem().empty(); }
  /// Whether the map's floor repeats anywhere, by the self-test recorded with the index
  /// (runtime::TestFloorRepeats): unknown (nullopt) when it was not run or placed nothing. Only
  /// a floor known not to repeat may be searched from off the map (design.md section 7b).
  std::optional<bool> floor_repeats() const { return floor_repeats_; }
  /// Loads the index now (it is loaded by the first Lookup otherwise); false with problem().
  bool Load() const;
  /// Features and bytes in memory once loaded (0 before).
  std::int64_t features() const;
  std::int64_t memory_bytes() const;
  double load_seconds() const;

  /// Candidate poses of the camera that took `frame` (an ideal image of `camera`, already at
  /// the expected image scale). Never throws for a frame without a place.
  PlaceLookup Lookup(const cv::Mat& frame, const camera::IdealCamera& camera) const;

 private:
  struct Loaded;
  static Eigen::Vector2d World(const Loaded& index, int feature);
  const mosaic::TileStore& store_;
  PlaceIndexOptions options_;
  std::optional<bool> floor_repeats_;
  mutable std::mutex mutex_;
  mutable bool tried_ = false;
  mutable std::string problem_;
  mutable std::unique_ptr<Loaded> loaded_;
};

}  // namespace mosaicloc::tracking
