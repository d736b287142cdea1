#pragma once

#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

namespace mosaicloc::tracking {

/// How templates are cut from a live frame.
enum class TemplateMode {
  kSpread,  ///< `count` square templates where texture is strongest, one per cell of a grid
  kTiled,   ///< the whole frame cut into `tile_cols` x `tile_rows` blocks: every pixel is used
};
/// "spread" or "tiled", as the localizer configuration names them.
const char* ToString(TemplateMode mode);
inline constexpr TemplateMode kTemplateModes[] = {TemplateMode::kSpread, TemplateMode::kTiled};

struct TemplateOptions {
  TemplateMode mode = TemplateMode::kSpread;
  int count = 4;        ///< kSpread: number of templates (the frame is split into this many cells)
  int size_px = 96;     ///< kSpread: template side, px
  int tile_cols = 4;    ///< kTiled
  int tile_rows = 3;    ///< kTiled
  /// Kept clear of the frame edge, px: gradients need neighbours, and a template at the very
  /// edge leaves the reference first when the frame is at the edge of the map.
  int border_px = 16;
  /// Minimum texture (smallest eigenvalue of the mean structure tensor of the template at
  /// half resolution, grey levels^2 per pixel^2) for a template to be used: a blank patch
  /// cannot be registered.
  double min_texture = 2.0;
  bool Check(std::string* why) const;
};

/// A rectangle of the live frame to register, and how textured it is.
struct TemplateSpot {
  cv::Rect rect;           ///< in frame pixels
  double texture = 0.0;    ///< smallest eigenvalue of the mean structure tensor over the rect
};

/// Picks templates in an 8-bit grey frame. kSpread divides the frame into a near-square grid of
/// `count` cells and keeps, in each, the window of size_px with the largest smallest eigenvalue
/// of its structure tensor (strong texture in both directions, so the match is defined in x
/// and y), judged at half resolution. Windows below min_texture are dropped, so fewer than
/// `count` may come back. Rectangles have even corners and sizes.
std::vector<TemplateSpot> SelectTemplates(const cv::Mat& frame, const TemplateOptions& options);
/// The same with the frame's 2x2 area average (`half`, frame size / 2) already computed.
std::vector<TemplateSpot> SelectTemplates(const cv::Mat& frame, const cv::Mat& half, const TemplateOptions& options);

/// Smallest eigenvalue of the mean structure tensor of an 8-bit image region, grey levels^2.
double TextureStrength(const cv::Mat& region);

}  // namespace mosaicloc::tracking
