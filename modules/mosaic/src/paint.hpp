#pragma once

#include <cstdint>

namespace mosaicloc::mosaic::internal {

/// A frame to paint: 8-bit pixels [0, width) x [0, height) with a border of at least
/// kPaintBorderPx replicated pixels around them in the same buffer, so every bicubic tap of
/// a position inside the frame can be read without a test.
struct PaintSource {
  const std::uint8_t* pixel00 = nullptr;  ///< frame pixel (0, 0)
  std::ptrdiff_t stride = 0;              ///< bytes per row
  int width = 0;
  int height = 0;
};
inline constexpr int kPaintBorderPx = 2;

/// Paints `count` accumulator pixels of one row. Accumulator pixel i takes the frame at
/// position (u, v) = (u0 + i du, v0 + i dv) (frame pixel centres at integers):
///   value  = bicubic interpolation of the frame there (Keys' kernel with a = -0.5, Catmull-Rom,
///            in float: no rounding to 8 bits and no clamping; the border replicates the edge
///            pixels),
///   weight = min(u + 1, width - u, v + 1, height - v): the distance in pixels to the edge of
///            the frame grown by half a pixel, so that every map pixel the frame overlaps is
///            painted (nothing where the weight is below 1e-3).
/// `accumulator` holds (a, b) float pairs: feather adds (value x weight, weight); best view
/// replaces (value, weight) when weight is larger than b.
void PaintRow(const PaintSource& source, double u0, double v0, double du, double dv, int count, float* accumulator,
              bool best_view);

/// PaintRow through a projective map, for a camera that looks at the floor at a slant:
/// accumulator pixel i takes the frame at ((u0 + i du) / w, (v0 + i dv) / w) with
/// w = w0 + i dw > 0. One pixel at a time.
void PaintRowProjective(const PaintSource& source, double u0, double v0, double w0, double du, double dv, double dw,
                        int count, float* accumulator, bool best_view);

}  // namespace mosaicloc::mosaic::internal
