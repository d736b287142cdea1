#include <string>

#include "mosaicloc/mosaic/tile_store.hpp"

namespace mosaicloc::mosaic {

std::string WeakBecause(const QualityCell& cell, const QualityThresholds& thresholds) {
  if (cell.mapped < thresholds.min_mapped) return {};
  const bool weak_texture = cell.texture >= 0.0f && cell.texture < thresholds.min_texture;
  const bool repeats = cell.ambiguity > thresholds.max_ambiguity;
  if (weak_texture && repeats) return "little texture, repeats";
  if (weak_texture) return "little texture";
  if (repeats) return "repeats";
  return {};
}

}  // namespace mosaicloc::mosaic
