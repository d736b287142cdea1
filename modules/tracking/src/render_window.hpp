#pragma once

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "mosaicloc/tracking/reference.hpp"

namespace mosaicloc::tracking::detail {

/// RenderWindow that says whether every pixel is known: then `*all_known` is true and `mask`
/// is left as it was (it would be all 255); otherwise `mask` is RenderWindow's.
cv::Mat RenderWindowKnown(const ReferenceRaster& reference, const Eigen::Matrix<double, 2, 3>& frame_to_raster,
                          const cv::Point& origin, const cv::Size& size, cv::Mat* mask, bool* all_known);

}  // namespace mosaicloc::tracking::detail
