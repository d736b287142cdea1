#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/mosaic/grid.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"

namespace mosaicloc::mosaic {

namespace internal {
struct PaintSource;
}

/// How overlapping frames combine into one map pixel. A frame gives each map pixel it
/// overlaps its bicubic value at the pixel's centre and a weight that falls linearly from the
/// frame centre to zero half a pixel beyond its edges.
enum class Blend {
  kFeather,   ///< weighted mean of every frame that saw the pixel
  kBestView,  ///< the value from the frame that saw the pixel closest to its centre
};
Blend ParseBlend(const std::string& name);  ///< "feather" or "best-view"; throws core::Error

/// Paints posed ideal images into a mosaic: level 0 accumulates in memory (8 bytes per
/// painted pixel), then Write() stores level 0 and the pyramid above it.
class MapBuilder {
 public:
  MapBuilder(const MapGrid& grid, Blend blend);

  /// Paints a CV_8UC1 ideal image of mm_per_px taken at world_from_camera.
  void AddFrame(const cv::Mat& image, const core::Pose2& world_from_camera, double mm_per_px);
  /// Paints an ideal image from a pinhole of focal length focal_px tilted against the floor:
  /// its optical axis meets the floor at world_from_view's position, its image x axis points
  /// along its yaw, and it shows mm_per_px of floor per pixel where it would looking straight
  /// down from the same distance (mm_per_px x focal_px); the floor's normal is
  /// (-tan tilt_y, tan tilt_x, 1) in camera axes (x right, y up the image, z back to the lens).
  /// Without tilt, the overload above.
  void AddFrame(const cv::Mat& image, const core::Pose2& world_from_view, double mm_per_px, double focal_px,
                double tilt_x_rad, double tilt_y_rad);
  /// Writes every level into the store in transactions of at most `batch` tiles.
  void Write(TileStore& store, const std::function<void(double)>& progress = {}, int batch = 64) const;

  std::int64_t frames() const { return frames_; }
  std::size_t tiles() const { return accumulators_.size(); }
  /// The level-0 tiles painted so far.
  std::vector<TileKey> TileKeys() const;
  /// Bytes of accumulators painted since the last BuildCheckpoint::Save: what the next one writes.
  std::size_t unsaved_bytes() const;

  /// Level 0 tile values as they will be stored (for tests).
  cv::Mat FinishTile(const TileKey& key) const;

 private:
  /// Per pixel, CV_32FC2: feather (sum of value x weight, sum of weight); best view
  /// (value, weight) of the best frame so far.
  using Accumulator = cv::Mat;

  friend class BuildCheckpoint;  // saves and restores the accumulators

  MapGrid grid_;
  Blend blend_;
  std::int64_t frames_ = 0;
  std::unordered_map<TileKey, Accumulator, TileKeyHash> accumulators_;
  std::unordered_set<TileKey, TileKeyHash> changed_;  ///< painted since the last checkpoint
  cv::Mat padded_;  ///< the frame being painted, with a replicated border

  /// Checks a frame, counts it and copies it into padded_, the source it is painted from.
  internal::PaintSource Pad(const cv::Mat& image);
  /// Over the level-0 raster columns [c0, c1] and rows [r0, r1], tile by tile (each created
  /// where there is none and marked changed): paint_row(row, x0, x1, pairs) for every raster
  /// row's run [x0, x1) in one tile, `pairs` its accumulator at x0.
  template <class PaintRun>
  void PaintFootprint(std::int64_t c0, std::int64_t c1, std::int64_t r0, std::int64_t r1, const PaintRun& paint_row);
};

/// Replaces level-0 tiles and recomputes every pyramid tile above them (reading their
/// unchanged siblings from the store), all in one transaction: a crash leaves either the old
/// map or the new one, never a pyramid that disagrees with level 0. With a `reason`, the write
/// is recorded in the map's history (TileStore::WriteRecorded) and its id returned.
std::optional<std::int64_t> WriteWithPyramid(TileStore& store, const std::vector<TileWrite>& level0,
                                             const std::string& reason = {});

/// What undoing a recorded update did.
struct RevertSummary {
  std::int64_t id = 0;
  std::string reason;         ///< the update's
  std::int64_t restored = 0;  ///< level-0 tiles put back as they were
  std::int64_t removed = 0;   ///< level-0 tiles it had added, removed
};
/// `map revert`: puts back the level-0 tiles update `id` replaced (removing those it added),
/// recomputes the pyramid above them and marks the update reverted, in one transaction.
/// Throws core::Error (invalid input) naming the map and update when it does not exist, is
/// already reverted, or a later update in force changed one of its tiles (that one is to be
/// reverted first).
RevertSummary RevertUpdate(TileStore& store, std::int64_t id);

}  // namespace mosaicloc::mosaic
