#include <string>

#include "mosaicloc/mosaic/quality.hpp"

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

QualityVerdict VerdictOf(const QualityCell& cell, const QualityThresholds& thresholds) {
  if (cell.mapped < thresholds.min_mapped) return QualityVerdict::kNotJudged;
  const std::string why = WeakBecause(cell, thresholds);
  if (why.find("repeats") != std::string::npos) return QualityVerdict::kRepeats;
  if (!why.empty()) return QualityVerdict::kLittleTexture;
  if (cell.ambiguity < -0.5f || cell.texture < 0.0f) return QualityVerdict::kPartlyJudged;
  return QualityVerdict::kGood;
}

}  // namespace mosaicloc::mosaic
