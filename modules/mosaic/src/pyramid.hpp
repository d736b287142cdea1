#pragma once

#include <array>

#include <opencv2/core/mat.hpp>

namespace mosaicloc::mosaic::internal {

/// One tile of the next pyramid level from its 2x2 children (row-major: top-left, top-right,
/// bottom-left, bottom-right; an empty Mat is an absent child). Each pixel is the mean of
/// the mapped ones among the four it covers, unmapped when none is.
cv::Mat Downsample(const std::array<cv::Mat, 4>& children, int tile_size_px);

}  // namespace mosaicloc::mosaic::internal
