#pragma once

#include <functional>
#include <string>
#include <vector>

#include "mosaicloc/mosaic/tile_store.hpp"

namespace mosaicloc::tracking {

/// How the map's quality layer is judged (design.md section 4): per tile of `level`, how much
/// texture a template there has, and whether the floor there has a copy nearby, before any
/// vehicle drives there.
struct MapQualityOptions {
  /// The cells are the tiles of this level (level 1 of a 0.25 mm/px map with 256 px tiles:
  /// 128 mm squares, about a view's height).
  int level = 1;
  /// Texture: the cell's level-0 floor is cut into windows of the tracker's template size,
  /// each judged as the tracker judges a template (TextureStrength at half resolution); the
  /// cell's figure is their median.
  int template_px = 96;
  /// Ambiguity: a square of floor `template_mm` wide, all of it mapped, centred in the cell as
  /// near its centre as the floor allows, on map level `search_level`, correlated (ZNCC) with the floor
  /// within `search_radius_mm` of the cell; the best match farther than `exclusion_mm` from its
  /// own place, among places whose window is all mapped. A floor that repeats scores near 1
  /// there, a natural floor less. The radius should reach the period of a repeating floor and
  /// the relocalization search (relocalize_radius_mm, 600 mm). A cell without such a square is
  /// not judged (-1).
  int search_level = 2;
  double template_mm = 64.0;
  double search_radius_mm = 600.0;
  double exclusion_mm = 8.0;
  /// Cells mapped less than this are not judged for ambiguity (-1).
  double min_mapped = 0.25;
  bool Check(std::string* why) const;
};

/// Judges every tile of options.level that holds mapped floor. `progress` gets 0..1. Throws
/// core::Error on bad options or an unreadable map.
std::vector<mosaic::QualityCell> AssessMapQuality(const mosaic::TileStore& store, const MapQualityOptions& options = {},
                                                  const std::function<void(double)>& progress = {});


}  // namespace mosaicloc::tracking
