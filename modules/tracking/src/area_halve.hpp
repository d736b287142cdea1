#pragma once

#include <opencv2/core/mat.hpp>

namespace mosaicloc::tracking::detail {

/// cv::resize(src, dst, src.size() / 2, 0, 0, INTER_AREA) of an 8-bit grey image, with the same
/// values: on even sides each output pixel is (a + b + c + d + 2) >> 2 of its 2x2 block, as
/// OpenCV rounds at scale 2, in a fraction of its per-call cost; odd sides (OpenCV's general
/// area weights) go to cv::resize. `dst` is reallocated only when its size or type differs.
/// Throws core::Error (invalid input) unless src is a non-empty CV_8UC1 of at least 2x2.
void HalveImage(const cv::Mat& src, cv::Mat& dst);

}  // namespace mosaicloc::tracking::detail
