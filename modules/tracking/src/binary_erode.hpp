#pragma once
// Erosion of a binary mask by a structuring element that is a run of pixels centred on each of
// its rows (a disc, an ellipse, a rectangle), in time proportional to the mask's pixels times
// the element's rows rather than its pixels.

#include <opencv2/core/mat.hpp>

namespace mosaicloc::tracking::detail {

/// cv::erode(mask, *out, element) with OpenCV's default border (everything outside the mask
/// counts as set), exactly, for a CV_8UC1 mask whose set pixels are nonzero and an element of
/// odd size centred in it whose set pixels on every row form one run centred on its centre
/// column (cv::getStructuringElement's MORPH_RECT, MORPH_CROSS and MORPH_ELLIPSE). The output
/// is 255 where the element fits and 0 elsewhere. Throws core::Error for another element.
void ErodeBinary(const cv::Mat& mask, const cv::Mat& element, cv::Mat* out);

}  // namespace mosaicloc::tracking::detail
