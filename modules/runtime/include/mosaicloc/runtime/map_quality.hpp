#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mosaicloc/mosaic/tile_store.hpp"
#include "mosaicloc/tracking/map_quality.hpp"

namespace mosaicloc::runtime {

/// Computes the map's quality layer (tracking::AssessMapQuality) and stores it in the map in
/// one transaction; `map build` does it for every map. Returns the cells.
std::vector<mosaic::QualityCell> AssessStore(mosaic::TileStore& store, const std::function<void(double)>& progress = {});

/// `mosaicloc map quality`: where on the map fixes will be weak, before a vehicle drives there.
struct MapQualityJob {
  std::filesystem::path map;
  std::filesystem::path out;  ///< a folder: quality.png, weak.csv, quality.json
  bool rebuild = false;       ///< compute the layer again (else the stored one; computed if absent)
  mosaic::QualityThresholds thresholds;
};

/// Neighbouring weak cells (8-connected) taken together: a stretch of lane to look at.
struct WeakStretch {
  std::int64_t cells = 0;
  double x0_mm = 0.0, y0_mm = 0.0, x1_mm = 0.0, y1_mm = 0.0;  ///< the cells' bounds
  double centre_x_mm = 0.0, centre_y_mm = 0.0;
  std::string reason;          ///< "little texture", "repeats" or both (the most cells')
  double min_texture = 0.0;    ///< the lowest of its cells
  double max_ambiguity = -1.0; ///< the highest of its cells
};

struct MapQualitySummary {
  bool computed = false;  ///< the layer was computed now (absent, or rebuild)
  double seconds = 0.0;   ///< computing it
  int level = 0;          ///< the cells are this level's tiles
  double cell_mm = 0.0;   ///< their side
  std::int64_t cells = 0;
  std::int64_t judged = 0;      ///< cells mapped enough to be judged (thresholds.min_mapped)
  std::int64_t weak_cells = 0;
  std::int64_t weak_texture = 0;
  std::int64_t repeating = 0;
  /// Judged cells without a template-sized square of floor (a lane's edge): their texture or
  /// copies could not be judged in full; not counted as weak or as good.
  std::int64_t unsearched = 0;
  std::vector<WeakStretch> stretches;  ///< largest first
  nlohmann::json json;                 ///< all of the above, as quality.json holds it
};

/// Reads (or computes and stores) the layer, writes DIR/quality.png (the map's floor tinted by
/// its cell: green good, amber little texture, red where the floor repeats, blue a lane's edge
/// not judged in full; a scale bar and a legend), DIR/weak.csv (the stretches) and DIR/quality.json (this summary), atomically.
MapQualitySummary MapQuality(const MapQualityJob& job, const std::function<void(double)>& progress = {});

}  // namespace mosaicloc::runtime
