#pragma once

#include "mosaicloc/mosaic/tile_store.hpp"

namespace mosaicloc::mosaic {

/// A cell's verdict as the picture, the console and the counts show it (values as the
/// console's API gives them).
enum class QualityVerdict {
  kNotJudged = -1,     ///< too little floor (below thresholds.min_mapped)
  kGood = 0,
  kLittleTexture = 1,
  kRepeats = 2,        ///< also when its texture is weak too
  kPartlyJudged = 3,   ///< a lane's edge: texture or copies could not be judged, nothing weak found
};
QualityVerdict VerdictOf(const QualityCell& cell, const QualityThresholds& thresholds);

}  // namespace mosaicloc::mosaic
