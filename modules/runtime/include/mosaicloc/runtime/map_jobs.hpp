#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mosaicloc/mosaic/builder.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"
#include "mosaicloc/runtime/map_poses.hpp"

namespace mosaicloc::runtime {

/// `mosaicloc map build`: every frame of a dataset painted at its pose into a new map.
struct MapBuildOptions {
  std::filesystem::path dataset;
  std::filesystem::path out;
  /// "estimate": the poses from the frames and encoders alone (EstimateMapPoses); "groundtruth":
  /// the dataset's ground truth; else a TUM file of vehicle poses.
  std::string poses = "estimate";
  std::filesystem::path report;  ///< with "estimate": the consistency report's directory, or empty
  /// Later drives over the same site painted into the same map: with "estimate" mapped with
  /// the first (MapPosesOptions::joined), with "groundtruth" at their own ground truth.
  std::vector<std::filesystem::path> joined;
  double join_start_sigma_mm = 20.0;  ///< MapPosesOptions::join_start_sigma_mm
  /// With "estimate": every frame taken to be at the calibrated height and straight down,
  /// without estimating it (mapping::MapperOptions::view_geometry off).
  bool flat_floor = false;
  std::string blend = "feather";      ///< mosaic::ParseBlend
  int tile_size_px = 256;
  int levels = 6;
  bool overwrite = false;  ///< replace an existing map
  bool resume = false;     ///< continue from OUT.checkpoint when there is one
  /// Painting's progress is saved at most this often, and so that saving costs at most a tenth
  /// of the painting; 0: after every frame.
  double checkpoint_s = 10.0;
};

struct MapBuildSummary {
  std::int64_t frames = 0;
  std::int64_t painted = 0;
  std::int64_t without_pose = 0;
  std::int64_t resumed_after = 0;  ///< frames a resumed build took from its checkpoint
  std::int64_t tiles = 0;
  std::int64_t level0_tiles = 0;
  std::int64_t place_features = 0;  ///< in the place index built with the map
  std::optional<MapPosesSummary> mapping;  ///< with poses "estimate"

  /// What `map build --json` prints: the map written (absolute path), the counts, the poses
  /// used, and with "estimate" the mapping's figures (MapPosesSummary::ToJson).
  nlohmann::json ToJson(const MapBuildOptions& options) const;
};

/// The map is written with its place index (IndexMap) and its quality layer (AssessStore).
/// With poses "estimate", the poses are estimated first and kept in OUT.poses.tum (and
/// OUT.poses.K.tum for the joined drives) until the map is written (a resumed build takes them
/// from there).
/// Writes the map under a temporary name and renames it into place at the end: an
/// interrupted build leaves no map (or the previous one). Progress is saved in OUT.checkpoint
/// as it goes; a resumed build continues from there, and since the saved accumulators are
/// exact, its map equals that of an uninterrupted build. The checkpoint is tied to the
/// inputs (their CRCs), so it is never resumed against changed ones. Throws core::Error
/// (invalid input) when OUT exists without `overwrite` or no frame has a pose.
MapBuildSummary BuildMap(const MapBuildOptions& options, const std::function<void(double)>& progress = {});

/// A level's tiled area, level pixels, inclusive.
struct MapExtent {
  std::int64_t col0 = 0, row0 = 0, col1 = -1, row1 = -1;
  bool empty() const { return col1 < col0; }
};
MapExtent LevelExtent(const mosaic::TileStore& store, int level);

/// `mosaicloc map info`: what a map holds, read without touching its tiles' pixels.
struct MapInfo {
  mosaic::MapGrid grid;
  std::vector<std::int64_t> tiles_per_level;  ///< index: level
  std::int64_t tiles = 0;
  std::uintmax_t bytes_on_disk = 0;  ///< the database and its write-ahead log
  /// The tiled area of level 0 in world mm (x0, y0, x1, y1); empty for a map without tiles.
  std::vector<double> extent_mm;
  /// The place index (design.md section 7b), when the map has one.
  std::optional<mosaic::PlaceIndexInfo> places;
  /// The quality layer (`map quality`), when the map has one.
  std::optional<mosaic::QualityInfo> quality;
  /// Recorded updates (`map history`), and how many of them are in force (not reverted).
  std::int64_t updates = 0;
  std::int64_t updates_in_force = 0;

  /// What `map info --json` prints: the grid, per-level tiles, extent, place index (with its
  /// floor self-test), quality layer and history counts; absent parts are null.
  nlohmann::json ToJson(const std::filesystem::path& map) const;
};
MapInfo InspectMap(const std::filesystem::path& map);

/// `mosaicloc map index`: builds (or rebuilds) a map's place index, which global
/// relocalization looks frames up in, and stores it in the map in one transaction.
/// The floor's self-test over a map's place index (design.md section 7b): views of the map,
/// rendered at up to `views` places spread over it (each at least 80 % mapped), searched for
/// everywhere as a frame without a prior is. A view found at its own place (within 2 mm) says
/// nothing against the floor; one found elsewhere, or ambiguous, is a copy: the floor repeats.
struct FloorRepeatTest {
  std::int64_t views = 0;
  std::int64_t own = 0;        ///< found at its own place
  std::int64_t elsewhere = 0;  ///< found elsewhere, or ambiguous
  double seconds = 0.0;
  /// "repeats", "does not repeat", or "unknown" (nothing placed).
  std::string Verdict() const;
  /// "VERDICT (N views searched for everywhere: K found at their own place, E elsewhere too)".
  std::string Describe() const;
  /// views, own, elsewhere, verdict, seconds.
  nlohmann::json ToJson() const;
  /// The test recorded with a map's index; nullopt when it was never run on that index.
  static std::optional<FloorRepeatTest> Of(const mosaic::PlaceIndexInfo& places);
};
/// Runs the self-test on an open store with a place index and records it with the index
/// (TileStore::WritePlaceRepeatTest). Every index build (IndexStore) runs it.
FloorRepeatTest TestFloorRepeats(mosaic::TileStore& store, int views = 24);

struct MapIndexSummary {
  std::int64_t cells = 0;
  std::int64_t features = 0;
  std::int64_t bytes = 0;
  double seconds = 0.0;
  FloorRepeatTest repeat_test;

  nlohmann::json ToJson(const std::filesystem::path& map) const;  ///< `map index --json`
};
MapIndexSummary IndexMap(const std::filesystem::path& map, const std::function<void(double)>& progress = {});
/// The same into an open, writable store.
MapIndexSummary IndexStore(mosaic::TileStore& store, const std::function<void(double)>& progress = {});

/// `mosaicloc map history`: the map's recorded updates, oldest first.
std::vector<mosaic::MapUpdate> MapHistory(const std::filesystem::path& map);
/// `map history --json`: the map and its updates (id, time, reason, tiles, reverted or null).
nlohmann::json MapHistoryJson(const std::filesystem::path& map, const std::vector<mosaic::MapUpdate>& history);

/// `mosaicloc map revert`: undoes a recorded update (mosaic::RevertUpdate), then rebuilds the
/// place index and the quality layer where the map has them, so that they describe its floor.
struct MapRevertSummary {
  mosaic::RevertSummary revert;
  bool reindexed = false;
  bool reassessed = false;

  nlohmann::json ToJson(const std::filesystem::path& map) const;  ///< `map revert --json`
};
MapRevertSummary RevertMapUpdate(const std::filesystem::path& map, std::int64_t id);

/// Reads every tile, the place index's cells, the quality layer's and the tiles the history
/// keeps; the problems of the damaged ones. *tiles gets the number of tiles read.
std::vector<std::string> CheckMap(const std::filesystem::path& map, std::size_t* tiles,
                                  const std::function<void(double)>& progress = {});

/// `mosaicloc map export`: a level of the map (or a region of it) as one PNG.
struct MapExportOptions {
  std::filesystem::path map;
  std::filesystem::path out;
  int level = -1;      ///< -1: the finest level that fits in 8192 px (level 0 with a region)
  std::string region;  ///< "x0,y0,x1,y1" in mm, or empty for all of the level
};
struct MapExportSummary {
  int level = 0;
  double mm_per_px = 0.0;
  std::int64_t cols = 0, rows = 0;
  bool damaged = false;  ///< damaged tiles were left black
};
MapExportSummary ExportMap(const MapExportOptions& options);

}  // namespace mosaicloc::runtime
