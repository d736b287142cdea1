#pragma once

#include <opencv2/core/mat.hpp>

namespace mosaicloc::tracking::detail {

/// The ranking map, `cells` (the frame in 8 x 8 px cells) of CV_64F: at each cell the smallest
/// eigenvalue of the structure tensor of the quarter-resolution frame averaged over the k x k
/// cells from it towards larger indices, the last row and column replicated past the edge.
/// That is MinEigen of the float maps of
///   quarter = resize(half, INTER_AREA); gx, gy = Sobel(quarter, CV_32F, scale 1/8);
///   sxx = resize(gx gx, INTER_AREA to cells) (and gx gy, gy gy);
///   mxx = boxFilter(sxx, k x k, anchor (0, 0), normalized, BORDER_REPLICATE),
/// computed exactly: each cell holds (sum of Gx^2 over its 2x2 quarter pixels) / 256, the box
/// sum in double of such values is exact, and boxFilter scales it by 1 / k^2 in double before
/// rounding to float, as RankingMap does. `half`'s sides must be multiples of 4, so that both
/// halvings are exact.
void RankingMap(const cv::Mat& half, int k, cv::Mat* eigen);
/// The same map through OpenCV's functions as written above, for frames whose halving does
/// not come out even; any sides.
void RankingMapOpenCv(const cv::Mat& half, int k, cv::Mat* eigen);

}  // namespace mosaicloc::tracking::detail
