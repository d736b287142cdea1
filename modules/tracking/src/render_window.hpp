#pragma once

#include <cmath>
#include <cstdint>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "mosaicloc/mosaic/renderer.hpp"
#include "mosaicloc/tracking/reference.hpp"

namespace mosaicloc::tracking::detail {

/// RenderWindow that says whether every pixel is known: then `*all_known` is true and `mask`
/// is left as it was (it would be all 255); otherwise `mask` is RenderWindow's.
cv::Mat RenderWindowKnown(const ReferenceRaster& reference, const Eigen::Matrix<double, 2, 3>& frame_to_raster,
                          const cv::Point& origin, const cv::Size& size, cv::Mat* mask, bool* all_known);

/// The raster block holding every point frame_to_raster maps `rect` to: columns
/// [col0, col1] and rows [row0, row1].
struct RasterBounds {
  std::int64_t col0 = 0, row0 = 0, col1 = 0, row1 = 0;
};
RasterBounds BoundsOf(const Eigen::Matrix<double, 2, 3>& frame_to_raster, const cv::Rect& rect);

/// The bounds plus `margin` px on every side, into `store` (see ReferenceRaster::Region).
void FetchRegion(const ReferenceRaster& reference, const RasterBounds& bounds, int margin, cv::Mat& store,
                 mosaic::RasterPatch* patch);

/// Bilinear sample of an image of T at (x, y); false when a source pixel is outside or unknown.
template <typename T>
inline bool Sample(const cv::Mat& image, const cv::Mat& mask, bool all_known, double x, double y, double* value) {
  const double fx0 = std::floor(x), fy0 = std::floor(y);
  const int ix = static_cast<int>(fx0), iy = static_cast<int>(fy0);
  if (ix < 0 || iy < 0 || ix + 1 >= image.cols || iy + 1 >= image.rows) return false;
  const T* p = image.ptr<T>(iy) + ix;
  const T* q = image.ptr<T>(iy + 1) + ix;
  if (!all_known) {
    const std::uint8_t* m = mask.ptr<std::uint8_t>(iy) + ix;
    const std::uint8_t* n = m + mask.step[0];
    if ((m[0] & m[1] & n[0] & n[1]) == 0) return false;
  }
  const double fx = x - fx0, fy = y - fy0;
  *value = (1.0 - fy) * ((1.0 - fx) * p[0] + fx * p[1]) + fy * ((1.0 - fx) * q[0] + fx * q[1]);
  return true;
}

}  // namespace mosaicloc::tracking::detail
