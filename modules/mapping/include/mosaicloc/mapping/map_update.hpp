#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/core/timestamp.hpp"
#include "mosaicloc/mosaic/renderer.hpp"
#include "mosaicloc/mosaic/tile_cache.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"

namespace mosaicloc::mapping {

/// Automatic map updates (design.md section 7e): floor that no longer looks as mapped (a
/// stain, a replaced tile, tyre marks) is painted over from the live view, once it has been
/// seen changed on several passes from a confident pose.
struct MapUpdateOptions {
  bool enabled = true;
  /// A cell is rewritten once it has been seen changed on this many passes in a row (at least
  /// 2: one frame, or one pass, never writes). A pass that sees it as mapped starts the count
  /// again.
  int passes = 2;
  /// Sightings of a cell further apart than this, seconds, are different passes.
  double pass_gap_s = 2.0;
  /// The floor is judged in square cells of this side, mm, fixed on the map's grid.
  double cell_mm = 16.0;
  /// A textured cell is changed when the live view and the map correlate (ZNCC) below this.
  double min_zncc = 0.6;
  /// ... and a cell next to a changed one, below this (a change's edge runs through cells).
  double border_zncc = 0.9;
  /// A cell whose grey levels vary by less than this (standard deviation, DN) is flat; a flat
  /// cell against a textured one is changed, two flat ones when their means differ by more
  /// than max_flat_change_dn.
  double flat_dn = 4.0;
  double max_flat_change_dn = 25.0;
  /// A frame votes only when at most this share of the cells it judges look changed: the fix
  /// stands on the rest of the view, and a view that is mostly different (a pose that is off,
  /// a kidnapped vehicle) says nothing about the floor.
  double max_changed_share = 0.4;
  /// ... and it judges at least this many cells.
  int min_cells = 6;
  /// A cell only partly mapped (at a lane's edge) is judged from a frame that holds all of its
  /// mapped part, on the pixels both the map and the view (margin_px inside its edge) hold,
  /// when they are at least this share of it; its rewrite repaints what the frame holds of it
  /// (all of the mapped part).
  double min_judged_share = 0.25;
  /// Confidence: the frame has a fix the filter took (NIS at most max_nis, chi-square with 3
  /// degrees of freedom), the filter has taken at least min_fixes_in_row fixes in a row since
  /// it last started or restarted, and the camera's position is known to max_sigma_mm (one
  /// standard deviation) after the fix.
  int min_fixes_in_row = 10;
  double max_nis = 7.81;
  double max_sigma_mm = 0.02;
  /// Where the map's quality layer (design.md section 4) says the floor repeats (a cell's
  /// ambiguity above this, mosaic::QualityThresholds::max_ambiguity), the view cannot tell the
  /// vehicle's place from a copy of it, so a frame centred there never votes: a vehicle
  /// carried one pattern period away and tracking the copy must not paint its floor there.
  double max_ambiguity = 0.85;
  /// A frame is compared once its view centre has moved this share of the view's shorter side
  /// from the last compared one's (cost: about a millisecond a comparison).
  double compare_every_fraction = 0.5;
  /// Cells nearer the frame's edge than this, pixels, are not judged.
  double margin_px = 8.0;
  bool Check(std::string* why) const;
};

/// One frame as the localizer left it.
struct UpdateFrame {
  core::Timestamp time;
  cv::Mat image;  ///< the ideal frame (not kept)
  core::Pose2 world_from_camera;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();  ///< of world_from_camera
  bool fixed = false;      ///< the filter took a fix from this frame
  bool restarted = false;  ///< ... by restarting from it (a relocalization, a re-anchoring)
  bool tracking = false;   ///< the lock is held and the mode is tracking on the map
  std::optional<double> nis;  ///< the fix's normalized innovation squared
};

/// What the updater did so far.
struct UpdateSummary {
  std::int64_t compared = 0;         ///< frames compared with the map
  std::int64_t mostly_changed = 0;   ///< ... of which looked changed over too much of the view to vote
  std::int64_t repeating = 0;        ///< confident frames not compared: the floor under them repeats
  std::int64_t updates = 0;          ///< updates written (each one transaction, in the map's history)
  std::int64_t cells_updated = 0;
  std::int64_t tiles_written = 0;    ///< level-0 tiles (the pyramid above them too)
  std::int64_t cells_pending = 0;    ///< cells seen changed, not (yet) on enough passes
  double seconds = 0.0;              ///< spent comparing and writing
  /// When each update was made and the camera pose it was painted from (for evaluation).
  std::vector<std::pair<core::Timestamp, core::Pose2>> painted;
  std::vector<std::string> warnings;
};

/// Compares confident frames with the map cell by cell and rewrites cells seen changed on
/// `passes` passes from the frame that completes the last one (design.md section 7e). Each
/// update is one transaction recorded in the map's history with the tiles it replaced
/// (`map history`, `map revert`); the cache is told at once. One thread.
class MapUpdater {
 public:
  /// `store` must be writable; `store` and `cache` (over it) must outlive the updater. Throws
  /// core::Error (invalid input) when options fail Check() or the map's resolution is not the
  /// camera's. The map's quality layer is read once here (a map without one: every floor is
  /// taken as not repeating; a damaged one: nothing is ever updated, and a warning says so).
  MapUpdater(mosaic::TileStore& store, mosaic::TileCache& cache, const camera::IdealCamera& camera,
             const MapUpdateOptions& options);

  void Frame(const UpdateFrame& frame);
  const UpdateSummary& summary() const;

 private:
  using CellIndex = std::pair<std::int64_t, std::int64_t>;
  struct CellIndexHash {
    std::size_t operator()(const CellIndex& cell) const {
      return static_cast<std::size_t>(static_cast<std::uint64_t>(cell.first) * 0x9e3779b97f4a7c15ULL ^
                                      static_cast<std::uint64_t>(cell.second) * 0xc2b2ae3d27d4eb4fULL);
    }
  };
  // A cell seen changed: passes completed changed in a row, the current pass's votes, and
  // when it was last seen.
  struct CellState {
    int changed_passes = 0;
    int changed_votes = 0;
    int same_votes = 0;
    core::Timestamp last_seen;
  };
  // Compares the frame with the map and votes; the cells due for rewriting.
  std::vector<CellIndex> Compare(const UpdateFrame& frame);
  // Paints the due cells from the frame, in one recorded transaction.
  void Update(const UpdateFrame& frame, const std::vector<CellIndex>& cells);

  mosaic::TileStore& store_;
  mosaic::TileCache& cache_;
  mosaic::MapRenderer renderer_;
  camera::IdealCamera camera_;
  MapUpdateOptions options_;
  int cell_px_ = 64;
  /// The quality layer's level, and its cells (tiles of that level) where the floor repeats.
  int quality_level_ = 0;
  std::unordered_set<CellIndex, CellIndexHash> repeating_;
  int fixes_in_row_ = 0;
  // The last compared frame's grey levels fitted to the map's: map = gain x live + offset.
  double gain_ = 1.0;
  double offset_ = 0.0;
  bool disabled_ = false;  ///< the quality layer is damaged: where the floor repeats is not known
  std::optional<core::Pose2> last_compared_;
  core::Timestamp last_compared_time_;
  std::unordered_map<CellIndex, CellState, CellIndexHash> cells_;
  mutable UpdateSummary summary_;
  cv::Mat region_store_;
};

}  // namespace mosaicloc::mapping
